"""Package discovery for setuptools (the rest of the configuration is in pyproject.toml).

The packages are found by setuptools' ``find_packages`` with include patterns, so a subpackage added or moved under
``gstyle_core`` or ``app`` goes into the wheel without editing a list. ``app.shaders`` and ``gstyle_core.bundled``
are added by name: their folders are the top-level ``shaders/`` and ``assets/`` (``[tool.setuptools.package-dir]``
in pyproject.toml), which a finder cannot see as subpackages, and pyproject.toml's ``packages.find`` cannot be
combined with named packages.
"""

from setuptools import find_packages, setup

CODE = find_packages(include=["gstyle_core", "gstyle_core.*", "app", "app.*"])
DATA = ["app.shaders", "gstyle_core.bundled"]  # package data only: shaders, the demo scene and the default painting

setup(packages=[*CODE, *DATA])
