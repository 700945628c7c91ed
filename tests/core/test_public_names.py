"""One address per name: every package name is declared once and fetched from its home.

The rules (issue 35, "one address per name"), read from the sources with ``ast``,
nothing imported:

- every module of the package declares its public names in a literal ``__all__``;
- a module's ``__all__`` lists only names the module itself defines (a ``def``, a
  ``class`` or an assignment at its top level, not an import and not ``x = imported``);
- no name is in two modules' ``__all__`` (a short list of same-named different things
  aside, each with its reason);
- every file of the repository (package, course files, tests, scripts, benchmarks)
  fetches a package name from the module that defines it: ``from M import n`` needs
  ``n`` in ``M.__all__`` (or, for a ``_private`` name, defined in ``M``), and ``M.n``
  on an imported module needs ``n`` defined in ``M``, never imported into it from
  another package module;
- no ``from x import y as y`` / ``import x as x`` (the re-export idiom), and a
  package's ``__init__.py`` imports nothing of the package.

The course files at the root (``so101_utils.py``, ``so101_mujoco_utils.py``, ...) are
the one facade: they import from the homes and hand the names on to the students.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "so101_kinematics"
SKIP = {".git", "__pycache__", "out", ".venv", ".pytest_cache", ".ruff_cache"}

SAME_NAME_DIFFERENT_THINGS = {
    "main": "each command's entry point (so101-check-fk, -ik, -traj): the module is the address",
    "build_request": "each checker's own request (FK, IK, trajectory, vision): one verb each",
    "gradescope_results": "the FK report's and the trajectory checker's results, different tests",
    "load_calibration": "the arm's JSON (calibration) vs the virtual arm's shipped file (virtual)",
    "metrics": "a trajectory's figures (planning) vs the simulator's tracking log (sim)",
    "figures": "a replay's figures (lab) vs a straight line's (sim): different runs",
    "replay": "a recording through the servo model (lab.replay) vs sim-vs-arm's (lab.sim_vs_arm)",
    "SETTLE_S": "the tracking run's settle time vs the straight-line run's: two settings",
}
"""Names in two modules' ``__all__`` that are different things; a new duplicate fails."""

SETTINGS_THAT_START_EQUAL = {
    "so101_kinematics.virtual.electrical.SUPPLY_V": "the virtual arm's own supply setting, "
    "the servo model's default today (scripts/mutation_check.py plants another)",
}
"""``name = imported`` kept as the module's own setting, not a second address."""


def module_name(path: Path, package: Path = PACKAGE) -> str:
    """so101_kinematics/hw/bus.py -> so101_kinematics.hw.bus (``__init__`` -> the package)."""
    name = ".".join(path.relative_to(package.parent).with_suffix("").parts)
    return name.removesuffix(".__init__")


def _bound(statements, names: dict[str, ast.stmt]) -> dict[str, ast.stmt]:
    for statement in statements:
        if isinstance(statement, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names[statement.name] = statement
        elif isinstance(statement, ast.Assign):
            for target in statement.targets:
                for node in ast.walk(target):
                    if isinstance(node, ast.Name):
                        names[node.id] = statement
        elif isinstance(statement, (ast.AnnAssign, ast.AugAssign)):
            if isinstance(statement.target, ast.Name):
                names[statement.target.id] = statement
        elif isinstance(statement, (ast.If, ast.Try)):
            _bound(statement.body, names)
            _bound(statement.orelse, names)
            for handler in getattr(statement, "handlers", ()):
                _bound(handler.body, names)
    return names


def defined_names(tree: ast.Module) -> dict[str, ast.stmt]:
    """The names a module binds at its top level itself (not by import) -> the statement."""
    return _bound(tree.body, {})


def imported_names(tree: ast.Module) -> dict[str, str]:
    """Every name a module imports (at any depth) -> the module it comes from."""
    found = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            for alias in node.names:
                found[alias.asname or alias.name] = node.module
        elif isinstance(node, ast.Import):
            for alias in node.names:
                found[alias.asname or alias.name.split(".")[0]] = alias.name
    return found


def declared_all(tree: ast.Module) -> list[str] | None:
    """The literal ``__all__`` of a module, or None when it has none."""
    for statement in tree.body:
        targets = (statement.targets if isinstance(statement, ast.Assign)
                   else [statement.target] if isinstance(statement, ast.AnnAssign) else [])
        if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
            return list(ast.literal_eval(statement.value))
    return None


def parse_package(package: Path = PACKAGE) -> dict[str, ast.Module]:
    """Every module of the package -> its syntax tree."""
    paths = sorted(package.rglob("*.py"))
    return {module_name(p, package): ast.parse(p.read_text()) for p in paths}


MODULES = parse_package()


def all_problems(name: str, tree: ast.Module) -> list[str]:
    """What is wrong with one module's ``__all__`` (missing, a name it does not define)."""
    declared = declared_all(tree)
    if declared is None:
        return [f"{name} declares no __all__"]
    problems = []
    defined, imported = defined_names(tree), imported_names(tree)
    for public in declared:
        statement = defined.get(public)
        if statement is None:
            where = f" (imported from {imported[public]})" if public in imported else ""
            problems.append(f"{name}.__all__ lists {public!r}, which {name} does not define"
                            f"{where}: list it in its home's __all__ and import it from there")
        elif (isinstance(statement, ast.Assign)
              and isinstance(statement.value, (ast.Name, ast.Attribute))
              and f"{name}.{public}" not in SETTINGS_THAT_START_EQUAL):
            root = statement.value
            while isinstance(root, ast.Attribute):
                root = root.value
            if isinstance(root, ast.Name) and root.id in imported:
                problems.append(f"{name}.__all__ lists {public!r}, an alias of "
                                f"{ast.unparse(statement.value)} (imported): a re-export")
    return problems


def fetch_problems(path: Path, modules: dict[str, ast.Module], root: Path = ROOT) -> list[str]:
    """Every package name a file fetches from a module that is not its home."""
    tree = ast.parse(path.read_text())
    public = {m: set(declared_all(t) or ()) for m, t in modules.items()}
    defined = {m: defined_names(t) for m, t in modules.items()}
    aliases, problems = {}, []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in modules and alias.asname:
                    aliases[alias.asname] = alias.name
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module in modules:
            for alias in node.names:
                if f"{node.module}.{alias.name}" in modules:
                    aliases[alias.asname or alias.name] = f"{node.module}.{alias.name}"
                elif alias.name not in (defined[node.module] if alias.name.startswith("_")
                                        else public[node.module]):
                    problems.append(f"{path.relative_to(root)}:{node.lineno} fetches "
                                    f"{alias.name} from {node.module}, which does not declare it "
                                    f"in __all__: import it from its home")
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Load)
                and isinstance(node.value, ast.Name) and node.value.id in aliases):
            module = aliases[node.value.id]
            came_from = imported_names(modules[module]).get(node.attr, "")
            if (node.attr not in defined[module] and f"{module}.{node.attr}" not in modules
                    and came_from.startswith("so101_kinematics")):
                problems.append(f"{path.relative_to(root)}:{node.lineno} reads "
                                f"{node.value.id}.{node.attr}, which {module} imports from "
                                f"{came_from}: use it from there")
    return problems


def reexport_idioms(tree: ast.Module) -> list[int]:
    """Lines of ``from x import y as y`` / ``import x as x``."""
    return [node.lineno for node in ast.walk(tree) if isinstance(node, (ast.Import, ast.ImportFrom))
            for alias in node.names if alias.asname and alias.asname == alias.name]


def repository_files() -> list[Path]:
    """Every Python file of the repository: package, course files, tests, scripts, benchmarks."""
    return sorted(p for p in ROOT.rglob("*.py") if not SKIP & set(p.relative_to(ROOT).parts))


@pytest.mark.parametrize("name", sorted(MODULES))
def test_each_module_declares_only_names_it_defines(name):
    assert all_problems(name, MODULES[name]) == []


def test_no_name_is_declared_by_two_modules():
    where = defaultdict(list)
    for name, tree in MODULES.items():
        for public in declared_all(tree) or ():
            where[public].append(name)
    twice = {n: ms for n, ms in where.items()
             if len(ms) > 1 and n not in SAME_NAME_DIFFERENT_THINGS}
    assert twice == {}, "one name, one address: rename one, or move the thing to one home"
    stale = {n for n in SAME_NAME_DIFFERENT_THINGS if len(where.get(n, ())) < 2}
    assert stale == set(), "no longer declared twice: drop from SAME_NAME_DIFFERENT_THINGS"


def test_every_file_fetches_each_package_name_from_its_home():
    problems = [p for path in repository_files() for p in fetch_problems(path, MODULES)]
    assert problems == []


def test_no_reexport_idiom_and_no_package_init_imports_the_package():
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text())
        assert reexport_idioms(tree) == [], f"{path}: `import x as x` re-exports x"
        if path.name == "__init__.py":
            fetched = [n.lineno for n in ast.walk(tree)
                       if isinstance(n, (ast.Import, ast.ImportFrom))
                       and getattr(n, "module", "") != "__future__"]
            assert fetched == [], f"{path} imports at lines {fetched}: a package re-exports nothing"


def test_the_rules_catch_a_facade(tmp_path):
    """A re-export planted in a copy of a small package is named by each rule."""
    package = tmp_path / "so101_kinematics"
    package.mkdir()
    (package / "__init__.py").write_text('"""Pkg."""\n\nfrom so101_kinematics.home import f\n')
    (package / "home.py").write_text('"""Home."""\n\n__all__ = ["f"]\n\n\ndef f():\n    """F."""\n')
    (package / "facade.py").write_text('"""Facade."""\n\nfrom so101_kinematics.home import f\n'
                                       "from so101_kinematics.home import f as f\n\n"
                                       'g = f\n__all__ = ["f", "g"]\n')
    user = tmp_path / "user.py"
    user.write_text("from so101_kinematics import facade\nfrom so101_kinematics.facade import f\n"
                    "facade.f()\n")
    modules = parse_package(package)
    assert set(modules) == {"so101_kinematics", "so101_kinematics.home", "so101_kinematics.facade"}
    assert len(all_problems("so101_kinematics.facade", modules["so101_kinematics.facade"])) == 2
    assert all_problems("so101_kinematics", modules["so101_kinematics"]) == [
        "so101_kinematics declares no __all__"]
    assert all_problems("so101_kinematics.home", modules["so101_kinematics.home"]) == []
    assert reexport_idioms(modules["so101_kinematics.facade"]) == [4]
    # the facade's own __all__ is wrong, so a user fetching f through it is named once by
    # the __all__ rule above; with an honest __all__, the fetch itself is named
    modules["so101_kinematics.facade"] = ast.parse('"""Facade."""\n\nfrom so101_kinematics.home '
                                                   'import f\n\n__all__ = []\n')
    problems = fetch_problems(user, modules, tmp_path)
    assert [p.split(" ")[1] for p in problems] == ["fetches", "reads"], problems
