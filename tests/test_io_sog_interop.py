"""SOG against PlayCanvas's own tool, ``@playcanvas/splat-transform``: a .sog it wrote (checked in, so CI checks it
without npm) decodes to the values the tool itself decodes; with the tool installed, it writes a .sog of
../shared's biker that we read the same way, and it reads ours (bundle and folder) back to the values we read."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from gstyle_core.assets import DEMO_SCENE
from gstyle_core.io import load_scene, save_scene
from gstyle_core.io.ply_compressed_write import morton_order
from gstyle_core.scene import GaussianScene
from tests.splat_transform_cli import SKIP_REASON, convert, splat_transform
from tests.test_io_web_export import random_scene

DATA = Path(__file__).resolve().parent / "data"
BIKER = Path(__file__).resolve().parents[2] / "shared" / "data" / "scenes" / "playcanvas" / "biker.spz"
FIELDS = ("means", "log_scales", "quats", "sh_dc", "sh_rest")


def assert_same_decode(ours: GaussianScene, theirs: GaussianScene) -> None:
    """Every field as the tool decodes it (its .ply); opacity within the tool's logit clamp at 1e-6 / 1 - 1e-6."""
    assert ours.count == theirs.count and ours.sh_degree == theirs.sh_degree
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(ours, field), getattr(theirs, field), err_msg=field)
    assert np.abs(ours.opacities - theirs.opacities).max() <= 1.5e-6


def position_steps(sog: Path) -> np.ndarray:
    """One 16-bit step of each axis in the log domain, from the bundle's meta.json."""
    means = json.loads(zipfile.ZipFile(sog).read("meta.json"))["means"]
    return (np.array(means["maxs"]) - np.array(means["mins"])) / 65535


def assert_near_source(decoded: np.ndarray, source: np.ndarray, steps: np.ndarray) -> None:
    """Each decoded position lies within one quantisation step of a source position (matched by nearest
    neighbour: the writer reorders), the step growing with |x| as the log transform's does."""
    distance, _ = cKDTree(source).query(decoded)
    bound = np.linalg.norm((np.abs(decoded) + 1) * steps, axis=1) * 1.001 + 1e-6
    assert np.all(distance <= bound), float((distance / bound).max())


def test_the_tools_checked_in_sog_decodes_as_the_tool_decodes_it():
    ours, report = load_scene(DATA / "demo1000_sh1.sog")
    theirs, _ = load_scene(DATA / "demo1000_sh1.splat-transform.ply")
    assert report.format == "sog-v2 (bundle)" and ours.count == 1000 and ours.sh_degree == 1
    assert json.loads(zipfile.ZipFile(DATA / "demo1000_sh1.sog").read("meta.json"))["shN"]["count"] == 512
    assert_same_decode(ours, theirs)
    source = load_scene(DEMO_SCENE)[0].means[:1000]  # tests/data/SOURCES.md: the demo's first 1,000 Gaussians
    assert_near_source(ours.means, source, position_steps(DATA / "demo1000_sh1.sog"))


def _tool() -> list[str]:
    tool = splat_transform()
    if tool is None:
        pytest.skip(SKIP_REASON)
    return tool


@pytest.mark.slow
@pytest.mark.skipif(not BIKER.is_file(), reason="../shared/data/scenes/playcanvas/biker.spz is absent")
def test_splat_transform_writes_a_biker_sog_we_read(tmp_path):
    tool = _tool()
    convert(tool, BIKER, tmp_path / "biker.sog")
    convert(tool, BIKER, tmp_path / "biker.ply")  # the source in the tool's own axes (its SPZ reading)
    convert(tool, tmp_path / "biker.sog", tmp_path / "back.ply")  # the tool's decode of its .sog
    ours, report = load_scene(tmp_path / "biker.sog")
    assert report.format == "sog-v2 (bundle)" and ours.count == 152_746
    assert_same_decode(ours, load_scene(tmp_path / "back.ply")[0])
    assert_near_source(ours.means, load_scene(tmp_path / "biker.ply")[0].means, position_steps(tmp_path / "biker.sog"))


@pytest.mark.slow
def test_splat_transform_reads_our_sog(tmp_path):
    tool = _tool()
    scenes = {"sh3": random_scene(n=3000, degree=3)}
    if BIKER.is_file():
        scenes["biker"] = load_scene(BIKER)[0]
    for name, scene in scenes.items():
        sog = tmp_path / f"{name}.sog"
        save_scene(scene, sog)
        save_scene(scene, tmp_path / name / "meta.json")
        ours = load_scene(sog)[0]
        for source in (sog, tmp_path / name / "meta.json"):
            convert(tool, source, tmp_path / f"{name}.theirs.ply")
            theirs = load_scene(tmp_path / f"{name}.theirs.ply")[0]
            assert theirs.count == scene.count
            assert_same_decode(ours, theirs)
        ref = scene.means[morton_order(scene.means)]
        step = position_steps(sog)
        assert np.all(np.abs(theirs.means - ref) <= 0.5 * step * (np.abs(ref) + 1) * 1.001 + 1e-6)
