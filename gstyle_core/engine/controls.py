"""The live controls: one row per value a user may change while a run goes on, and everything derived from it.

A row (``Control``) says what the control is called and shows (label, range, log scale, format, tooltip), how it
reads and writes ``StylizeSettings`` (the write checks the value and says why it is refused), what the engine must
do when it changes (``Effect``) and, when ``gstyle stylize`` takes it too, its command-line option. From ``CONTROLS``
come ``Stylizer.set_params`` (``apply_controls``), ``ui_params`` (``read_controls``), ``resolve_settings``'
overrides of these names, the CLI options (``add_control_arguments``), the studio's slider rows and checkboxes
(``panel_controls``), the worker's and the studio's names (``control_names``, ``painting_controls``) and the
options the studio's engine factory passes on (``cli_control_names``). A new control is one row.

Torch-free: the studio imports it at start (``settings.py``, which needs torch, is imported only inside functions).
"""

from __future__ import annotations

import argparse
import copy
import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

from ..style.mix import weights_with_mix
from ..style.painting_size import check_style_scale
from .arg_types import check_palette_match, on_off_arg, palette_match_arg, style_scale_arg

# A ``settings.StylizeSettings``: settings.py imports this module, so nothing here imports it back (not even for
# typing); the controls read and write its attributes by name.
Settings = Any


class Effect(enum.Flag):
    """What the engine does when a control changes (``Stylizer.set_params`` carries them out)."""

    NONE = 0
    REWEIGHT = enum.auto()  # new λ weights for the objective: a term whose weight turns non-zero is built then
    STYLE_FEATURES = enum.auto()  # the painting's features are taken again (stroke size, luminance) or re-weighted
    CONTENT_TARGETS = enum.auto()  # past the start's colour match: the content targets are matched again
    RESTORE_CHROMA = enum.auto()  # with keep colours on: every Gaussian takes its ground truth's chroma back at once
    LR_SCHEDULE = enum.auto()  # the learning-rate schedule is rescaled (read at the next step: nothing to do now)
    NEXT_SPLIT = enum.auto()  # read at the next colour-gradient split (nothing to do now)
    NEXT_STEP = enum.auto()  # read at the next stylization step (nothing to do now)
    PALETTE_MATCH = enum.auto()  # a finished final colour match is blended again at the new strength, at once
    # (``phases/colour_match.py``); before the final match runs, it reads the strength then


@dataclass(frozen=True)
class CliOption:
    """A control's ``gstyle stylize`` option (``--`` + its name with dashes; default None: the preset's value)."""

    help: str
    type: Callable[[str], Any] = float  # argparse's type; a ValueError reads "invalid float value"
    metavar: str | None = None
    switch: bool = False  # a flag without a value (store_true)


@dataclass(frozen=True)
class Control:
    """One live control: what it shows, how it reads and writes the settings, what a change makes the engine do."""

    name: str  # set_params / ui_params key
    label: str  # the panel's label
    default: float  # the forward-facing preview's value (the panel's before a scene's preset is known;
    # ``settings.preset_values`` gives every preset's and scene kind's)
    low: float  # the panel's range
    high: float
    log: bool  # the panel's slider is on a logarithmic scale
    tooltip: str
    effects: Effect
    read: Callable[[Settings], float]
    write: Callable[[Settings, Any], None]  # ValueError saying why a value is refused
    widget: str = "slider"  # "slider" or "checkbox" (0/1)
    fmt: str = "%.3g"  # the slider's number format
    tolerance: float = 0.0  # a change of the read value by at most this is none (float noise)
    with_paintings: bool = False  # belongs to the paintings of a mix: shown beside the second painting, and a new
    # set of paintings brings its own value (not carried over)
    cli: CliOption | None = None

    @property
    def flag(self) -> str:
        """The command-line option, e.g. ``--lambda-nnfm``."""
        return "--" + self.name.replace("_", "-")


def _write_weight(term: str) -> Callable[[Settings, Any], None]:
    def write(s: Settings, value: Any) -> None:
        s.weights = replace(s.weights, **{term: float(value)})

    return write


def _write_strength(s: Settings, value: Any) -> None:
    if not float(value) >= 0:
        raise ValueError(f"strength must be 0 or more, got {value}")
    s.strength = float(value)


def _write_style_scale(s: Settings, value: Any) -> None:
    s.style_scale = check_style_scale(value)


def _write_palette_match(s: Settings, value: Any) -> None:
    s.palette_match = check_palette_match(value)


def _write_switch(name: str) -> Callable[[Settings, Any], None]:
    """The writer of an on/off setting (a checkbox: any true value is on)."""
    def write(s: Settings, value: Any) -> None:
        setattr(s, name, bool(value))

    return write


def _write_split_rate(s: Settings, value: Any) -> None:
    s.split_rate = float(value)


def _write_lr(s: Settings, value: Any) -> None:
    """The starting learning rate; the final one keeps its ratio to it."""
    ratio = s.lr_end / s.lr_start
    s.lr_start = float(value)
    s.lr_end = float(value) * ratio


def _read_mix(s: Settings) -> float:
    """The last painting's share of a mix (0 with one painting)."""
    return s.style_weights[-1] / sum(s.style_weights) if len(s.style_weights) > 1 else 0.0


def _write_mix(s: Settings, value: Any) -> None:
    """The last painting takes ``value``, the others share the rest (the engine holds one weight per painting)."""
    if len(s.style_weights) > 1:
        s.style_weights = weights_with_mix(s.style_weights, float(value))
    elif float(value) != 0.0:
        raise ValueError("the style mix needs a second style image")


def _term(term: str, label: str, default: float, low: float, high: float, tooltip: str, cli_help: str) -> Control:
    """The row of a loss term's λ (the panel adds an on/off checkbox to every ``lambda_`` row)."""
    return Control(f"lambda_{term}", label, default, low, high, True, tooltip, Effect.REWEIGHT,
                   read=lambda s: getattr(s.weights, term), write=_write_weight(term),
                   cli=CliOption(f"weight of the {cli_help}"))


CONTROLS: tuple[Control, ...] = (
    _term("clip", "large patterns", 10.0, 1e-2, 1e3,
          "Large patterns: the painting's large-scale patterns and layout of colour. The engine's CLIP term "
          "(lambda_clip, --lambda-clip: CLIP ViT-B/32 embeddings of the render and the painting).",
          "CLIP (or substitute) large-pattern term"),
    _term("nnfm", "brush strokes", 100.0, 1e-1, 1e4,
          "Brush strokes: the painting's strokes and local texture. The engine's NNFM term (lambda_nnfm, "
          "--lambda-nnfm: nearest-neighbour feature matching of VGG features).",
          "NNFM brush-stroke term"),
    _term("multiscale", "broad strokes", 100.0, 1e-1, 1e4,
          "Broad strokes: the painting's larger strokes and shapes. The engine's multi-scale NNFM term "
          "(lambda_multiscale, --lambda-multiscale: matched on the render and the painting both shrunk 2x, 4x and "
          "8x). On by default, at the brush strokes' weight, when no CLIP weights are found; follows the stroke size "
          "and the style strength.",
          "broad-strokes term (multi-scale NNFM: the painting's larger strokes and shapes; default λ_NNFM "
          "without CLIP weights, 0 with them)"),
    _term("content", "keep the scene", 0.05, 1e-4, 10.0,
          "Keep the scene: keeps it recognisable. The engine's content term (lambda_content, --lambda-content: VGG "
          "features of the render held to the scene's own).",
          "content preservation"),
    _term("tv", "smoothness", 1e-4, 1e-7, 1e-1,
          "Smoothness: smooths noisy pixels. The engine's TV term (lambda_tv, --lambda-tv: total variation of the "
          "render).",
          "total-variation smoothness"),
    _term("chroma_tv", "colour smoothness", 1500.0, 1.0, 1e5,
          "Colour smoothness (the engine's chroma TV term, lambda_chroma_tv, --lambda-chroma-tv): the total "
          "variation of the render's colour (not its light and dark) at the "
          "pixels each level renders, so single splats do not each take a hue of their own (confetti at the "
          "display's size) while edges and shading stay. Strongest at the finer levels (Refine), whose pixels are "
          "the display's.",
          "colour-smoothness term (total variation of the render's chroma, per pixel)"),
    _term("edges", "edges kept", 0.0, 1.0, 1e5,
          "Edges kept (the engine's edges term, lambda_edges, --lambda-edges): the render's light-and-dark edges "
          "(luminance gradients, pixel to pixel) held to "
          "the scene's, so faces, outlines and shapes stay legible under the strokes while colours and texture "
          "change; more keeps more structure and lets less of the painting's texture in. At every level's pixels.",
          "edge-keeping term (luminance gradients held to the scene's, per pixel)"),
    Control("strength", "style strength", 1.0, 0.1, 100.0, True,
            "Style strength: multiplies the style terms (large patterns, brush strokes, broad strokes) against keep "
            "the scene; 1 keeps their weights as they are, more paints harder, less keeps more of the scene.",
            Effect.REWEIGHT, read=lambda s: s.strength, write=_write_strength,
            cli=CliOption("style strength: scales the style terms (CLIP, NNFM, broad strokes) against content; "
                          "default 1")),
    Control("style_scale", "stroke size", 1.0, 0.25, 4.0, True,
            "Stroke size: how large the painting's brush strokes come out on the scene. 2: strokes and patterns "
            "twice as large, fewer of them across the view; 0.5: half as large, finer. It changes their size, not "
            "how strong the style is (that is style strength); the broad-strokes term carries the large ones "
            "(docs/notes/texture-scale.md). From the next step on (--style-scale; the painting is matched at this "
            "times the working width).",
            Effect.STYLE_FEATURES, read=lambda s: s.style_scale, write=_write_style_scale,
            cli=CliOption("stroke size: the painting is matched at S × the working width (2: at twice that size, "
                          "0.5: half; visible with the broad-strokes term, docs/notes/texture-scale.md); default 1",
                          type=style_scale_arg, metavar="S")),
    Control("palette_match", "palette match", 1.0, 0.0, 1.0, False,
            "Palette match: how far the finished colours move onto the painting's palette in the last colour match. "
            "1: the method's full match (the painting's colours); 0: the colours as the strokes left them; between: "
            "a blend of the two. A finished result changes at once, without running again; during a run the end "
            "takes it (--palette-match; with keep colours it blends the luminance match alone).",
            Effect.PALETTE_MATCH, read=lambda s: s.palette_match, write=_write_palette_match, fmt="%.2f",
            cli=CliOption("palette match of the final colour match: 1 the method's full match onto the painting's "
                          "palette, 0 the colours as the strokes left them, between a blend; default 1",
                          type=palette_match_arg, metavar="T")),
    Control("keep_colours", "keep colours", 0.0, 0.0, 1.0, False,
            "Keep the scene's colours: it keeps its hues and takes only the painting's light and dark pattern "
            "(colour match and networks on luminance; each Gaussian's own chroma restored after every step). "
            "Turned on mid-run the hues come back at once; turned off, the painting's colours are matched again "
            "from the next step and at the end (--keep-colours).",
            Effect.STYLE_FEATURES | Effect.CONTENT_TARGETS | Effect.RESTORE_CHROMA,
            read=lambda s: float(s.keep_colours), write=_write_switch("keep_colours"), widget="checkbox",
            cli=CliOption("keep the scene's hues and take only the painting's luminance pattern", switch=True)),
    Control("colour_field", "coherent strokes", 0.0, 0.0, 1.0, False,
            "Coherent strokes: neighbouring Gaussians' colours move together. A coarse colour field over the scene "
            "(cells of 8 px x the stroke size at its middle distance) steps beside each Gaussian's own colour, each "
            "at half the learning rate, so strokes come as wide as the painting's and the stroke size shows. On by "
            "default with the broad-strokes term; read from the next step (--colour-field 0/1).",
            Effect.NEXT_STEP, read=lambda s: float(s.colour_field), write=_write_switch("colour_field"),
            widget="checkbox",
            cli=CliOption("coherent strokes: a coarse colour field steps beside each Gaussian's colour (1 on, 0 off; "
                          "default on with the broad-strokes term, docs/notes/texture-scale.md)", type=on_off_arg,
                          metavar="0|1")),
    Control("split_rate", "split rate", 0.05, 1e-3, 0.5, True,
            "Fraction of Gaussians split where the style gradient is largest (finer detail, more Gaussians).",
            Effect.NEXT_SPLIT, read=lambda s: s.split_rate, write=_write_split_rate,
            cli=CliOption("fraction of Gaussians split by colour gradient")),
    Control("lr", "learning rate", 0.1, 1e-3, 1.0, True, "Starting learning rate of the colour optimisation.",
            Effect.LR_SCHEDULE, read=lambda s: s.lr_start, write=_write_lr),
    Control("style_mix", "style mix", 0.0, 0.0, 1.0, False,
            "Share of the second painting: 0 is the first alone, 1 the second alone. Every style term is the "
            "weighted sum of its terms against each painting, and the colours match the weighted palette; changed "
            "mid-run it applies from the next step (--style A --style B --style-weights).",
            Effect.STYLE_FEATURES | Effect.CONTENT_TARGETS, read=_read_mix, write=_write_mix, fmt="%.2f",
            tolerance=1e-9, with_paintings=True),
)


def control(name: str) -> Control:
    """The row called ``name`` (``KeyError`` for none)."""
    for row in CONTROLS:
        if row.name == name:
            return row
    raise KeyError(name)


def term_label(term: str) -> str:
    """A loss term (a ``StyleWeights`` field, e.g. ``multiscale``) as people read it: its λ row's label ("broad
    strokes", "keep the scene"; an older "lambda " prefix left out); the term's own name when it has no row."""
    try:
        return control(f"lambda_{term}").label.removeprefix("lambda ")
    except KeyError:
        return term


def control_names() -> tuple[str, ...]:
    """Every name ``Stylizer.set_params`` accepts (the worker's and the studio's ``set_params`` commands)."""
    return tuple(row.name for row in CONTROLS)


def cli_control_names() -> tuple[str, ...]:
    """The controls that ``gstyle stylize`` (and the studio's engine factory, through it) takes as options."""
    return tuple(row.name for row in CONTROLS if row.cli is not None)


def painting_controls() -> frozenset[str]:
    """The controls that belong to the paintings of a mix (a new set of paintings brings its own)."""
    return frozenset(row.name for row in CONTROLS if row.with_paintings)


def panel_controls(widget: str) -> tuple[Control, ...]:
    """The rows the panel's parameter section shows as ``widget`` ("slider" or "checkbox"), in table order."""
    return tuple(row for row in CONTROLS if row.widget == widget and not row.with_paintings)


def read_controls(settings: Settings) -> dict[str, float]:
    """Every control's value in ``settings`` (keep colours as 0/1; the mix: the last painting's share)."""
    return {row.name: float(row.read(settings)) for row in CONTROLS}


def apply_controls(settings: Settings, values: Mapping[str, Any]) -> Effect:
    """Set the controls in ``values`` (None: keep) on ``settings``, in place; returns what the engine must do now.

    Every value is checked before anything changes: an unknown name or a refused value raises ``ValueError`` and
    leaves ``settings`` as it was. Only the rows whose value changed contribute their effects."""
    rows = {row.name: row for row in CONTROLS}
    unknown = set(values) - set(rows)
    if unknown:
        raise ValueError(f"unknown parameters: {', '.join(sorted(unknown))}")
    given = {name: value for name, value in values.items() if value is not None}
    trial = copy.deepcopy(settings)
    for name, value in given.items():
        rows[name].write(trial, value)
    effects = Effect.NONE
    for name, value in given.items():
        row = rows[name]
        before = float(row.read(settings))
        row.write(settings, value)
        if not abs(float(row.read(settings)) - before) <= row.tolerance:
            effects |= row.effects
    return effects


def add_control_arguments(parser: argparse.ArgumentParser) -> None:
    """The controls' ``gstyle stylize`` options (default None: the preset's value)."""
    for row in CONTROLS:
        if row.cli is None:
            continue
        if row.cli.switch:
            parser.add_argument(row.flag, action="store_true", default=None, help=row.cli.help)
        else:
            parser.add_argument(row.flag, type=row.cli.type, default=None, metavar=row.cli.metavar,
                                help=row.cli.help)
