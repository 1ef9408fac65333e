"""Errors that carry a one-line, user-facing reason."""


class GStyleError(Exception):
    """Base class for errors the CLI and the app show as one line, without a traceback."""


class SceneFormatError(GStyleError):
    """A scene file is malformed, truncated or of an unknown format."""


class CameraFormatError(GStyleError):
    """A camera file is malformed or missing."""


class StyleImageError(GStyleError):
    """A style image cannot be read or used."""


class WeightsUnavailableError(GStyleError):
    """Network weights (VGG, CLIP) are not available offline."""


class OutputWriteError(GStyleError, OSError):
    """An output could not be written (no space, permission denied, read-only file system, a directory in its
    place). The message is one line naming the path and the cause; no partial file is left. Also an ``OSError``
    (``errno`` and ``filename`` set), so callers that tolerate a failed write still catch it."""

    def __init__(self, path: object, cause: str, errno: int | None = None) -> None:
        super().__init__(f"cannot write {path}: {cause}")
        self.errno, self.filename, self.cause = errno, str(path), cause

    def __str__(self) -> str:
        return str(self.args[0])

    def __reduce__(self):
        return type(self), (self.filename, self.cause, self.errno)


def one_line_error(exc: BaseException) -> str:
    """``Type: message`` on one line (for a UI's line or an error that wraps another); a ``GStyleError`` is already
    worded for the user (e.g. ``cannot write PATH: no space left on the device``, as the CLI prints it): its message
    alone."""
    text = " ".join(str(exc).split()) or "(no message)"
    return text if isinstance(exc, GStyleError) else f"{type(exc).__name__}: {text}"
