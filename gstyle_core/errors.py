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
