"""The layout's rules (ARCHITECTURE.md's invariants), read from the source with ``ast``: which package may import
which, the studio's classes without mixins and without state written from two modules, and every path and name the
architecture page cites exists."""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GL_OR_UI = ("moderngl", "glfw", "imgui_bundle", "OpenGL", "app")


def module_name(path: Path) -> str:
    """``gstyle_core/engine/stylizer.py`` -> ``gstyle_core.engine.stylizer`` (a package's ``__init__`` is the
    package)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path, source: str | None = None) -> set[str]:
    """Every module ``path`` (or ``source`` as if it were there) imports, absolute, relative ones resolved
    (function-level imports included)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8") if source is None else source)):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[: len(package.split(".")) - node.level + 1] if node.level else []
            target = ".".join([*base, node.module] if node.module else base)
            found.add(target)
            found.update(f"{target}.{alias.name}" for alias in node.names)
    return found


def sources(folder: str) -> list[Path]:
    """The Python files of ``folder`` (relative to the root)."""
    return sorted((ROOT / folder).rglob("*.py"))


def offending_imports(folder: str, forbidden: tuple[str, ...]) -> list[str]:
    """``file: module`` for each import under ``folder`` of a module in (or under) ``forbidden``."""
    bad = []
    for path in sources(folder):
        for target in imports_of(path):
            if any(target == f or target.startswith(f + ".") for f in forbidden):
                bad.append(f"{path.relative_to(ROOT)}: {target}")
    return sorted(set(bad))


def test_the_core_never_imports_gl_or_the_ui():
    assert offending_imports("gstyle_core", GL_OR_UI) == []


def test_the_engine_never_imports_the_command_line_or_the_batch():
    assert offending_imports("gstyle_core/engine", ("gstyle_core.cli", "gstyle_core.batch")) == []


def test_only_the_command_line_imports_the_command_line():
    cli = ROOT / "gstyle_core" / "cli"
    bad = [f"{path.relative_to(ROOT)}: {target}" for path in sources("gstyle_core") if cli not in path.parents
           for target in imports_of(path) if target == "gstyle_core.cli" or target.startswith("gstyle_core.cli.")]
    assert bad == []


def test_the_rules_catch_a_forbidden_import():
    """The checks above can fail: a relative import of the command line from the engine resolves to it."""
    probe = ROOT / "gstyle_core" / "engine" / "phases" / "probe.py"
    found = imports_of(probe, "def f():\n    from ...cli.stylize import stylize_command\n")
    assert "gstyle_core.cli.stylize" in found


def class_bases() -> dict[str, int]:
    """``module.Class`` -> its number of base classes, for every class in ``app/``."""
    counts = {}
    for path in sources("app"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                counts[f"{module_name(path)}.{node.name}"] = len(node.bases)
    return counts


def test_no_studio_class_has_more_than_two_bases():
    assert {name: n for name, n in class_bases().items() if n > 2} == {}


def families(trees: list[ast.AST]) -> dict[str, str]:
    """Class name -> the name of its family: classes joined by inheritance among ``trees`` share one ``self``
    (a mixin's attributes are its subclass's), so they share a family."""
    parent: dict[str, str] = {}

    def root(name: str) -> str:
        while parent.setdefault(name, name) != name:
            name = parent[name]
        return name

    classes = [n for tree in trees for n in ast.walk(tree) if isinstance(n, ast.ClassDef)]
    ours = {cls.name for cls in classes}  # a base from elsewhere (Exception, NamedTuple) joins nothing
    for cls in classes:
        for base in cls.bases:
            base_name = base.id if isinstance(base, ast.Name) else getattr(base, "attr", None)
            if base_name in ours:
                parent[root(base_name)] = root(cls.name)
    return {name: root(name) for name in list(parent)}


def written_attributes(tree: ast.AST, family: dict[str, str] | None = None) -> list[tuple[str, str]]:
    """(owner, attribute) for each attribute assignment in ``tree``: ``self.x = …`` in class C gives (C's family,
    x); ``self.part.x = …`` or ``obj.x = …`` gives (part, x) / (obj, x): the last two names of the target."""
    found, family = [], family or {}

    def targets(node: ast.AST) -> list[ast.AST]:
        if isinstance(node, ast.Assign):
            return [t for tgt in node.targets for t in (tgt.elts if isinstance(tgt, ast.Tuple) else [tgt])]
        return [node.target] if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []

    for cls in [n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)]:
        for node in ast.walk(cls):
            for target in targets(node):
                if not isinstance(target, ast.Attribute):
                    continue
                owner = target.value
                if isinstance(owner, ast.Name):
                    me = family.get(cls.name, cls.name)
                    found.append((me if owner.id == "self" else owner.id, target.attr))
                elif isinstance(owner, ast.Attribute):
                    found.append((owner.attr, target.attr))
    return found


def attribute_writers() -> dict[tuple[str, str], set[str]]:
    """(owner, attribute) -> the ``app/`` modules that write it."""
    trees = {path: ast.parse(path.read_text(encoding="utf-8")) for path in sources("app")}
    family = families(list(trees.values()))
    writers: dict[tuple[str, str], set[str]] = defaultdict(set)
    for path, tree in trees.items():
        for key in written_attributes(tree, family):
            writers[key].add(module_name(path))
    return writers


def test_no_studio_attribute_is_written_from_two_modules():
    shared = {f"{owner}.{attr}": sorted(mods) for (owner, attr), mods in attribute_writers().items() if len(mods) > 1}
    assert shared == {}


def test_the_attribute_check_sees_a_shared_write():
    """The check can fail: the same part's field written in two modules' classes is found, and a mixin's
    ``self.x`` is its subclass's."""
    one = ast.parse("class A:\n    def f(self):\n        self.region.enabled = True\n")
    two = ast.parse("class B:\n    def g(self):\n        self.region.enabled = False\n        self.mine = 1\n")
    mixed = ast.parse("class Mixin:\n    def h(self):\n        self.mine = 2\nclass B(Mixin):\n    pass\n")
    family = families([two, mixed])
    assert ("region", "enabled") in written_attributes(one)
    assert {("region", "enabled"), ("B", "mine")} <= set(written_attributes(two, family))
    assert ("B", "mine") in written_attributes(mixed, family)


CODE = re.compile(r"`([^`\n]+)`")
PATH_LIKE = re.compile(r"^[\w./-]+(/|\.py|\.md|\.toml|\.glsl)$|^[\w-]+/[\w./-]*$")
NAME_LIKE = re.compile(r"^([A-Z_a-z][\w]*)(\.[A-Za-z_]\w*)?(\(\))?$")
PREFIXES = ("", "gstyle_core/", "app/", "gstyle_core/engine/")


def defined_names() -> set[str]:
    """Every class, function, method and module-level name defined in the project's Python code."""
    names = set()
    for folder in ("gstyle_core", "app", "tests", "bench"):
        for path in sources(folder):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, (ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)):
                    names.add(node.name)
                elif isinstance(node, ast.Assign):
                    names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return names


def cited(page: Path) -> tuple[list[str], list[str]]:
    """The paths and the code names a page cites in backticks (commands and prose in backticks left out)."""
    paths, names = [], []
    for text in CODE.findall(page.read_text(encoding="utf-8")):
        if " " in text or text.startswith(("gstyle ", "python ")):
            continue
        if PATH_LIKE.match(text):
            paths.append(text)
        elif NAME_LIKE.match(text) and (not text.islower() or "_" in text or text.endswith("()")):
            names.append(text)  # CamelCase, snake_case or called: a code name, not a word
    return paths, names


def test_architecture_page_cites_only_what_exists():
    page = ROOT / "ARCHITECTURE.md"
    paths, names = cited(page)
    assert len(paths) > 30 and len(names) > 15  # the page is read, not skipped
    missing_paths = [p for p in paths if not any((ROOT / prefix / p.rstrip("/")).exists() for prefix in PREFIXES)]
    known = defined_names() | {"self"}
    missing_names = [n for n in names if any(part not in known for part in re.split(r"\.", n.removesuffix("()")))
                     and n.removesuffix("()") not in {"gstyle_core", "app"}]
    assert missing_paths == [] and missing_names == []


@pytest.mark.parametrize("text", ["gstyle_core/engine/no_such_module.py", "app/no_such_part.py"])
def test_architecture_check_finds_a_missing_path(text):
    assert not any((ROOT / prefix / text).exists() for prefix in PREFIXES)
