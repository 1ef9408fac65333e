"""What a scene loader found and changed: the ``LoadReport`` shown by ``gstyle info``."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class LoadReport:
    """Outcome of ``load_scene``: format, counts, SH degree, repairs made and warnings."""

    format: str
    path: str
    count_in_file: int
    count_loaded: int
    sh_degree: int
    repairs: list[str] = field(default_factory=list)
    dropped: int = 0
    warnings: list[str] = field(default_factory=list)

    def summary(self) -> str:
        """A few human-readable lines (format, counts, repairs, warnings)."""
        lines = [
            f"{self.path}: {self.format}",
            f"Gaussians: {self.count_loaded:,} loaded of {self.count_in_file:,} in file"
            + (f" ({self.dropped:,} dropped)" if self.dropped else ""),
            f"SH degree: {self.sh_degree}",
        ]
        lines += [f"repair: {r}" for r in self.repairs]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)
