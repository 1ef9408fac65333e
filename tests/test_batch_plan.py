"""``gstyle batch --plan plan.toml`` (issue #50 item 1): runs whose settings vary, each run × scene × painting a job
named ``SCENE__PAINTING__RUN``; shared options at the top level, a run's own win; a bad plan is one line naming the
key and the file. The jobs run the stand-in engine in the test's process (``batch_worker.py``)."""

from __future__ import annotations

import pytest
from batch_worker import use_tiny_engine
from PIL import Image
from test_batch import TAILS, make_inputs, rows_of

from gstyle_core.batch.report import CELL_WIDTH, TEXT_HEIGHT
from gstyle_core.cli import run

PICTURE = -(-CELL_WIDTH // 3)  # the stand-in's after pictures are 3:1


@pytest.fixture
def inputs(tmp_path, monkeypatch) -> dict:
    """``test_batch``'s two scenes and two paintings, beside the plan file."""
    return make_inputs(tmp_path, monkeypatch)


def write_plan(inputs: dict, text: str):
    plan = inputs["out"].with_name("plan.toml")
    plan.write_text(text)
    return plan


def plan_batch(inputs: dict, plan, *extra: str) -> list[str]:
    return ["batch", "--plan", str(plan), "--out", str(inputs["out"]), "--checkpoint-every", "0", "--jobs", "1",
            *extra]


PLAN = """
scenes = ["scene1.ply", "scene2.ply"]   # from the plan's folder
styles = ["red.png"]
strength = 1.5
keep-colours = true

[[run]]
name = "soft"
strength = 0.5

[[run]]
name = "wide"
working_width = 128
refine-widths = [512, 1024]
styles = ["red.png", "blue.png"]
scenes = ["scene2.ply"]
"""


def test_every_run_scene_and_painting_is_a_job_with_its_run_s_settings(inputs, monkeypatch, capsys):
    built = []
    use_tiny_engine(monkeypatch.setattr, built)
    plan = write_plan(inputs, PLAN)
    assert run(plan_batch(inputs, plan, "--strength", "3", "--preset", "balanced")) == 0
    names = ["scene1__red__soft", "scene2__red__soft", "scene2__red__wide", "scene2__blue__wide"]
    out = inputs["out"]
    for name in names:
        assert all((out / (name + tail)).is_file() for tail in TAILS), name
    settings = [(r.preset, r.overrides["strength"], r.overrides["keep_colours"], r.overrides["working_width"],
                 r.overrides["refine_widths"]) for r in built]
    assert settings == [("balanced", 0.5, True, None, None)] * 2 + [("balanced", 1.5, True, 128, (512, 1024))] * 2
    rows = rows_of(out)
    assert [(r["run"], r["status"]) for r in rows] == [("soft", "done")] * 2 + [("wide", "done")] * 2
    assert rows[0]["scene"] == str(out.parent / "scene1.ply")
    with Image.open(out / "contact_sheet.png") as sheet:  # rows: soft × 2 scenes, wide × 1; columns: red, blue
        assert sheet.size == (2 * CELL_WIDTH, 3 * (PICTURE + TEXT_HEIGHT))
        assert sheet.getpixel((3 * CELL_WIDTH // 2, PICTURE // 2)) == (255, 255, 255)  # soft has no blue
        blue = sheet.getpixel((3 * CELL_WIDTH // 2, 2 * (PICTURE + TEXT_HEIGHT) + PICTURE // 2))
    assert blue[2] > 150 > blue[0]
    capsys.readouterr()
    assert run(plan_batch(inputs, plan)) == 0 and len(built) == 4  # the same names again: all done already
    assert "4 jobs, 4 done already; nothing to run" in capsys.readouterr().err


def test_a_plan_without_runs_is_one_run_and_the_command_line_gives_its_files(inputs, monkeypatch):
    built = []
    use_tiny_engine(monkeypatch.setattr, built)
    plan = write_plan(inputs, 'preset = "final"\n')
    assert run(plan_batch(inputs, plan, "--scenes", inputs["scenes"][0], "--styles", *inputs["paintings"])) == 0
    assert sorted(p.name for p in inputs["out"].glob("*.ply")) == ["scene1__blue.ply", "scene1__red.ply"]
    assert [r.preset for r in built] == ["final", "final"]


@pytest.mark.parametrize("text, error", [
    ("strenght = 2\n", "strenght: not a gstyle stylize option a plan can set (docs/batch.md)"),
    ("[[run]]\nname = 'a'\nstrength = 'much'\n",
     "run 'a': strength: argument --strength: invalid float value: 'much'"),
    ("[[run]]\nname = 'a'\npreset = 'best'\n", "run 'a': preset: argument --preset: invalid choice: 'best'"),
    ("[[run]]\nname = 'a'\nkeep-colours = 1\n", "run 'a': keep-colours: give true or false, got 1"),
    ("[[run]]\nname = 'a'\nout = 'x.ply'\n", "run 'a': out: not a gstyle stylize option a plan can set"),
    ("[[run]]\nname = 'a'\nthreads = 2\n", "run 'a': threads: not a gstyle stylize option a plan can set"),
    ("[[run]]\nstrength = 2\n", "run 1: name: give each run a name of letters, digits"),
    ("[[run]]\nname = 'a b'\n", "run 1: name: give each run a name"),
    ("[[run]]\nname = 'a'\n[[run]]\nname = 'a'\n", "run 2: name: two runs are named 'a'"),
    ("[[run]]\nname = 'a'\nscenes = []\n", "run 'a': scenes: give a list of files, got []"),
    ("scenes = ['scene1.ply']\n", "styles: none given (in the run, the plan's top level or --styles)"),
    ("strength = 2\n[run]\nname = 'a'\n", "run: give each run as a [[run]] table"),
    ("strength = \n", "not a TOML plan: "),
])
def test_a_bad_plan_is_one_line_naming_the_key_and_the_file(inputs, capsys, text, error):
    plan = write_plan(inputs, "styles = ['red.png']\n" * ("styles" not in error) + text)
    assert run(plan_batch(inputs, plan, *([] if "scenes" in text else ["--scenes", inputs["scenes"][0]]))) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"gstyle batch: error: {plan}: ") and error in err[0], err
    assert not inputs["out"].exists()


def test_a_missing_plan_is_one_line(inputs, capsys):
    assert run(plan_batch(inputs, inputs["out"].with_name("nowhere.toml"))) == 2
    assert capsys.readouterr().err.startswith("gstyle batch: error: No such file or directory: ")
