"""What the panel shows (``PanelState``, filled by the app each frame) and what it asks for (``Command``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .params import param_rows

VIEW_MODES = ("stylized", "original", "compare", "ground truth", "take")
TURNTABLE_FORMATS = ("mp4", "gif", "png frames")
MAX_TURNTABLE_FRAMES = 3600


@dataclass
class Command:
    """Something the user asked for; the app (not the panel) carries it out."""

    name: str
    args: dict[str, Any] = field(default_factory=dict)


@dataclass
class PanelState:
    """Everything the panel displays; the app fills it each frame."""

    scene_path: str = ""
    result_line: str = ""  # the scene is a stylized result (app/result_files.py): what it is; "" for other scenes
    result_source: str = ""  # the original scene it came from ("" when its summary names none)
    result_source_found: bool = False
    result_continuable: bool = False  # its run was kept and its original found: Continue can load it
    style_path: str = ""
    style_texture: int | None = None  # GL texture id of the style thumbnail
    style_size: tuple[int, int] = (1, 1)
    style2_path: str = ""  # a second painting mixed in (empty: one painting)
    style2_texture: int | None = None
    style2_size: tuple[int, int] = (1, 1)
    phase: str = "-"
    step: int = 0
    total_steps: int = 0
    eta_seconds: float | None = None
    gaussians: int = 0
    fps: float = 0.0
    paused: bool = False
    running: bool = False  # the worker steps the engine now (``WorkerState.stepping``)
    error: str | None = None
    device_failed: bool = False  # the error was the GPU's: "Continue on the CPU" is offered under it
    failed: bool = False  # an engine error stopped the run (nothing steps until Continue, a move or a restart)
    continue_from: int | None = None  # after it, the last finished step: "Continue from step N" is offered
    stopped: str = ""  # why Pause / Resume and Step cannot work now ("" when they can): their tooltip, disabled
    device: str = ""  # what the engine computes on ("cpu", "cuda", "mps"; "": no engine)
    device_name: str = ""  # the same in words (the card)
    devices: tuple[str, ...] = ("cpu",)  # what the worker could compute on (the quality section offers a move)
    status: str = ""
    loss_history: list[dict[str, float]] = field(default_factory=list)
    params: dict[str, float] = field(default_factory=lambda: {p.key: p.default for p in param_rows()})
    view_mode: str = "stylized"
    has_ground_truth: bool = False
    camera_count: int = 0
    fov_deg: float = 50.0
    show_help: bool = False
    resume_available: bool = False  # a saved session of this scene + style exists (cache folder)
    resume_step: int | None = None  # the worker died: the step its last save holds, where Resume (and Space) go on
    decisions: dict[str, Any] = field(default_factory=dict)  # the engine's, as forwarded by the worker
    defaults: dict[str, float] = field(default_factory=dict)  # "reset" values: the preset the scene resolved to
    switched_off: dict[str, float] = field(default_factory=dict)  # λ of terms turned off, restored when turned on
    clip_name: str = "CLIP"  # what the CLIP term is: "CLIP" or "coarse (CLIP substitute)" without CLIP weights
    camera_names: list[str] = field(default_factory=list)
    camera_index: int = -1  # the scene camera last snapped to (-1: none)
    viewer_notes: list[str] = field(default_factory=list)  # what the viewer skips (SH, sorts, uploads)
    turntable_frames: int = 60
    turntable_format: str = "mp4"  # one of TURNTABLE_FORMATS
    video_running: bool = False  # a turntable video is being rendered in the background
    video_fraction: float = 0.0
    video_label: str = ""
    take_names: list[str] = field(default_factory=list)  # the last exports kept as takes, newest first
    take_labels: list[str] = field(default_factory=list)
    take_settings: list[str] = field(default_factory=list)  # per take: its settings in one line
    take_thumbnails: list[tuple[int, tuple[int, int]] | None] = field(default_factory=list)  # (GL texture, size)
    take_differs: list[bool] = field(default_factory=list)  # per take: it differs from the view now (T starts there)
    save_folder: str = ""  # where Ctrl+S writes now
    output_folder: str = ""  # the output folder (absolute): screenshots, videos, takes.json, exports by default
    undo_note: str = ""  # the step Ctrl+Z takes back ("" when none), and the one Ctrl+Shift+Z takes again
    redo_note: str = ""
    take_shown: int = -1  # the take loaded in the take view (-1: none)
    compare_with_take: bool = False  # the compare view's right side is that take (else the original)
    divider: float = 0.5  # the compare view's split, fraction of the width
    region_enabled: bool = False  # the selection tool is on: its selection is highlighted and used at (re)start
    region_mode: str = "box"  # "box" (the 3D box below) or "rectangle" (the last Shift + drag in the view)
    region_box: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # x0,y0,z0,x1,y1,z1 in scene coordinates
    region_feather: float = 0.0  # the box's soft edge in scene units (the style fades out over it; 0: hard)
    region_selected: int = 0  # Gaussians of the input scene in the selection
    region_total: int = 0
    region_in_engine: str = ""  # what the running engine was started with ("" : the whole scene)
    region_outline: list[tuple[float, float, float, float]] = field(default_factory=list)  # box edges (view px)
    selection_outline: list[tuple[float, float, float, float]] = field(default_factory=list)  # selected (view px)
    region_drag: tuple[float, float, float, float] | None = None  # the rectangle being dragged (view pixels)
    panel_rect: tuple[float, float, float, float] | None = None  # the docked panel (x0, y0, x1, y1); None: collapsed
    view_rect: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0)  # the scene's part (x, y, width, height)
    browser: Any = None  # the studio's file browser (app/file_browser.FileBrowser) while it is open
    dialog_note: str = ""  # a native file dialog is open: what it is for (the panel offers the studio's browser)
    preset: str = ""  # the quality the engine runs at ("" until it is built)
    quality: str = "preview"  # the quality chosen in the panel (a restart applies it)
    quality_estimates: dict[str, float | None] = field(default_factory=dict)  # seconds per preset on this scene
    width: int = 0  # the width the engine works at now (px)
    levels: list[int] = field(default_factory=list)  # the widths of the run, coarse to fine
    next_width: int | None = None  # Refine's width (None: no finer level possible)
    refine_note: str = ""
    summary_line: str = ""  # the finished run's result (its speckle at a display's size), as the engine words it
    grain: str = ""  # its speckle ratio at that size ("0.61"; "-" without detail to compare; "" without a figure)
