"""Packaging: every package declares in package.xml what it imports, its setup.py installs files
that exist and says what package.xml says, and no pac package imports another in a cycle."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

SRC = Path(__file__).resolve().parents[1] / "src"
LOCK = SRC.parent / "requirements.lock"

#: Imported module -> the rosdep key package.xml declares it by.
ROSDEP_KEYS = {
    "numpy": "python3-numpy",
    "scipy": "python3-scipy",
    "yaml": "python3-yaml",
    "matplotlib": "python3-matplotlib",
    "tqdm": "python3-tqdm",
    "rclpy": "rclpy",
    "rcl_interfaces": "rcl_interfaces",
    "diagnostic_msgs": "diagnostic_msgs",
    "lifecycle_msgs": "lifecycle_msgs",
    "ament_index_python": "ament_index_python",
    "domain_coordinator": "domain_coordinator",
}
#: Imported module -> its PyPI distribution: libraries with no rosdep key, pinned in
#: requirements.lock instead (and named in a comment of package.xml).
PYPI_ONLY = {
    "rosbags": "rosbags",
    "mcap": "mcap",
    "zstandard": "zstandard",
    "lz4": "lz4",
    "numba": "numba",
    "llvmlite": "llvmlite",
    "distributed": "distributed",
    "foxglove": "foxglove-sdk",
}


def packages() -> list[Path]:
    return sorted(p.parent for p in SRC.glob("*/package.xml"))


def imports(package: Path) -> dict[str, set[str]]:
    """Top-level module -> the files of the package that import it (absolute imports, stdlib excluded)."""
    found: dict[str, set[str]] = {}
    for path in sorted((package / package.name).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top != package.name:
                    found.setdefault(top, set()).add(path.name)
    return found


def declared(package: Path) -> set[str]:
    return set(
        re.findall(
            r"<(?:exec_|build_|build_export_)?depend>\s*([^<\s]+)\s*<", (package / "package.xml").read_text()
        )
    )


@pytest.mark.parametrize("package", packages(), ids=lambda p: p.name)
def test_package_xml_declares_every_import(package):
    deps = declared(package)
    locked = {line.split("==")[0].lower() for line in LOCK.read_text().splitlines() if "==" in line}
    missing = []
    for module, files in sorted(imports(package).items()):
        if module.startswith("pac_"):
            key = module
        elif module in ROSDEP_KEYS:
            key = ROSDEP_KEYS[module]
        elif module in PYPI_ONLY:
            assert PYPI_ONLY[module] in locked, (
                f"{module} (imported by {sorted(files)}) not in requirements.lock"
            )
            continue
        else:
            pytest.fail(
                f"{package.name} imports {module} ({sorted(files)}): add it to ROSDEP_KEYS or PYPI_ONLY"
            )
        if key not in deps:
            missing.append(f"{key} (imported by {', '.join(sorted(files))})")
    assert missing == [], f"{package.name}/package.xml does not declare: {missing}"


@pytest.mark.parametrize(
    "package", [p for p in packages() if (p / "setup.py").exists()], ids=lambda p: p.name
)
def test_setup_py_installs_what_exists_and_agrees_with_package_xml(package):
    setup = (package / "setup.py").read_text()
    for pattern in re.findall(r'glob\("([^"]+)"\)', setup):
        assert list(package.glob(pattern)), f"{package.name}/setup.py installs {pattern}: no such file"
    text = re.search(r"description=\(?\s*((?:\"[^\"]*\"\s*)+)", setup)
    assert text, "setup.py has no description"
    description = "".join(re.findall(r'"([^"]*)"', text.group(1)))
    xml = re.search(r"<description>([^<]*)</description>", (package / "package.xml").read_text())
    assert xml and xml.group(1) == description


def module_imports(package: Path) -> dict[str, set[str]]:
    """Module -> the modules of its own package it imports (relative or absolute, any depth)."""
    root = package / package.name
    modules = {
        path.relative_to(root).with_suffix("").as_posix().replace("/", "."): path
        for path in root.rglob("*.py")
    }
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        parent = name.rsplit(".", 1)[0] if "." in name else ""
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = parent if node.level == 1 else parent.rsplit(".", node.level - 1)[0]
                    stem = ".".join(x for x in (base, node.module or "") if x)
                elif node.module and node.module.split(".")[0] == package.name:
                    stem = node.module.partition(".")[2]
                else:
                    continue
                targets = [stem] if stem in modules else []
                targets += [f"{stem}.{a.name}" if stem else a.name for a in node.names]
            elif isinstance(node, ast.Import):
                own = [a.name for a in node.names if a.name.split(".")[0] == package.name]
                targets = [name.partition(".")[2] for name in own]
            else:
                continue
            deps |= {t for t in targets if t in modules and t != name}
        graph[name] = deps
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` (a path that returns to its start), None if there is none."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(name: str, path: list[str]) -> list[str] | None:
        state[name] = 1
        for dep in sorted(graph.get(name, ())):
            if state.get(dep) == 1:
                return [*path, name, dep]
            if dep not in state and (found := visit(dep, [*path, name])):
                return found
        state[name] = 2
        return None

    for name in sorted(graph):
        if name not in state and (found := visit(name, [])):
            return found
    return None


def test_find_cycle_finds_one():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


@pytest.mark.parametrize("package", packages(), ids=lambda p: p.name)
def test_no_import_cycle_between_the_modules_of_a_package(package):
    """Within a package too: a module that imports one that imports it back (even at the bottom of
    the file) is two ideas in the wrong homes."""
    cycle = find_cycle(module_imports(package))
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_no_import_cycle_between_packages():
    graph = {p.name: {m for m in imports(p) if m.startswith("pac_")} for p in packages()}
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(name: str, path: list[str]) -> None:
        state[name] = 1
        for dep in sorted(graph.get(name, ())):
            if state.get(dep) == 1:
                pytest.fail("import cycle: " + " -> ".join([*path, name, dep]))
            if dep not in state:
                visit(dep, [*path, name])
        state[name] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [])


@pytest.mark.slow
def test_design_doc_maps_every_package():
    """docs/design.md's package map has one row per package, none that does not exist, and each
    row names exactly the pac packages its package imports."""
    text = (SRC.parent / "docs" / "design.md").read_text()
    block = text.split("## Package map", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in block.splitlines() if line.startswith("| `pac_")]
    mapped = {line.split("`")[1]: line.rstrip(" |").rsplit("|", 1)[1].strip() for line in rows}
    assert sorted(mapped) == sorted(p.name for p in packages())
    for package in packages():
        real = sorted(m for m in imports(package) if m.startswith("pac_"))
        assert mapped[package.name] == (", ".join(real) or "—"), package.name
