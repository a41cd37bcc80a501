"""The layers of docs/architecture.md, kept by CI: every ``brakethermo`` import of every
module (including those inside functions) is checked against what its package may use."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "brakethermo"

# package -> the brakethermo packages it may import (itself always allowed). Base modules:
# errors, config, vocabulary, numeric, the package root (__version__).
BASE = {"errors", "config", "vocabulary", "numeric", "__init__"}
ALLOWED: dict[str, set[str]] = {
    "estimation": BASE,
    "io": BASE,
    "thermal": BASE,
    "rigs": BASE,
    "models": BASE | {"estimation", "thermal", "rigs"},
    "results": BASE | {"io", "estimation", "thermal", "rigs", "models"},
    "diagnosis": BASE | {"estimation", "models"},
    "report": BASE | {"io", "thermal", "rigs", "models", "results"},
    "pipelines": BASE | {"io", "estimation", "thermal", "rigs", "models", "results",
                         "diagnosis", "report"},
    # the simulator is its own program: the session writer, the disc datasheet and its
    # loader, the shared names — no estimator code (SIM_MODULES below)
    "sim": BASE | {"io", "thermal"},
    "cli": BASE | {"io", "thermal", "pipelines", "report", "sim", "models", "results"},
}
# Known debt, each with its issue; the test fails when one is fixed (remove it here) or
# when a new one appears.
KNOWN: set[tuple[str, str]] = set()
# Within a layer that may import io, physics must not write files: only these modules of
# thermal/ models/ rigs/ may import io, and only to read (the datasheet loaders).
PHYSICS_IO_READERS: set[str] = set()


def _imports(path: Path) -> set[str]:
    """The brakethermo packages ``path`` imports (top-level package names)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "brakethermo":
                out.add(parts[1] if len(parts) > 1 else "__init__")
    return out


def _violations() -> set[tuple[str, str]]:
    found = set()
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE)
        if len(rel.parts) == 1:
            continue  # the base modules
        pkg = rel.parts[0]
        allowed = ALLOWED[pkg] | {pkg}
        for target in _imports(path):
            if target.removesuffix(".py") not in allowed:
                found.add((rel.as_posix(), target))
    return found


def test_every_package_has_a_rule() -> None:
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert packages <= set(ALLOWED), f"add a layer rule for {packages - set(ALLOWED)}"


def test_imports_follow_the_layers() -> None:
    found = _violations()
    new = found - KNOWN
    assert not new, "imports against the layers (docs/architecture.md): " + ", ".join(
        f"{f} -> {t}" for f, t in sorted(new))
    fixed = KNOWN - found
    assert not fixed, f"known debt fixed, remove it from KNOWN: {sorted(fixed)}"


def test_physics_and_models_write_no_files() -> None:
    for pkg in ("thermal", "models", "rigs", "estimation"):
        for path in (PACKAGE / pkg).rglob("*.py"):
            rel = path.relative_to(PACKAGE).as_posix()
            if rel in PHYSICS_IO_READERS:
                continue
            assert "io" not in _imports(path), f"{rel} imports io (the models return data)"


# Of io and thermal, the simulator's code may call exactly these modules: the session
# writer and the disc datasheet (geometry and its loader). The FE model, the readers and
# everything else the estimator is made of are not called by the truth (importing the
# writer still runs io's package __init__; what is checked is what sim imports directly).
SIM_MODULES = {"brakethermo.io.writers", "brakethermo.thermal.disc"}


def _module_imports(path: Path, package: str = "brakethermo.sim") -> set[str]:
    """The full names of the brakethermo modules ``path`` imports from: ``import a.b``,
    ``from a.b import c``, ``from brakethermo import thermal`` and relative imports
    (resolved against ``package``, the file's own)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parent, *([base] if base else [])])
            out.add(base)
            if base == "brakethermo":  # from brakethermo import thermal: the package itself
                out.update(f"brakethermo.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return {m for m in out if m.startswith("brakethermo.")}


def test_the_simulator_uses_only_the_writer_and_the_datasheet() -> None:
    for path in (PACKAGE / "sim").rglob("*.py"):
        for module in _module_imports(path):
            pkg = module.split(".")[1]
            if pkg in {"io", "thermal"}:
                assert module in SIM_MODULES, (
                    f"sim/{path.name} imports {module}: the truth uses only the session"
                    " writer and the datasheet")


def test_the_checker_sees_imports_inside_functions(tmp_path: Path) -> None:
    probe = tmp_path / "probe.py"
    probe.write_text("def f():\n    from brakethermo.pipelines.estimate import x\n")
    assert _imports(probe) == {"pipelines"}


def test_no_function_is_over_80_lines() -> None:
    """Every function of the package reads in one sitting (the house issue's rule)."""
    long = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > 80:
                    long.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {node.name}"
                                f" ({lines} lines)")
    assert not long, "functions over 80 lines:\n" + "\n".join(long)
