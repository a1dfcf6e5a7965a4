"""Mutation testing of pac's safety-critical code: small defects planted one at a time, the fast tests
run on each, a report of what they caught.

``make mutation`` (after ``make setup``; ``ARGS="--modules kernels guard"`` narrows it, ``--list``
only lists the mutants).  For every function in :data:`SCOPE` the script plants each mutant of a
small set of operators (a comparison turned into its neighbour or its negation, ``and`` / ``or``
swapped, a ``not`` dropped, ``+`` / ``-`` and ``*`` / ``/`` swapped, ``min`` / ``max`` swapped, a
numeric constant changed, ``True`` / ``False`` swapped) into the *installed* copy of the module,
runs that module's tests (the ``make test-fast`` kinds: unit and offline, not slow, not live) with
a timeout, and restores the file.  Killed: a test failed or errored (or the run timed out, counted
apart); survived: every test passed.  The report (``reports/mutation/<module>.md`` and
``summary.md``) lists every mutant, and every survivor with the argument in ``notes.json`` (why it
is equivalent, or what test is missing), keyed like the results below.

Results are kept between runs (``<scope>.json``) by each mutant's key: its function's name and a
digest of that function's source, the change, and which occurrence of it. Lines may move; a
function whose source changed has its mutants run again. ``--survivors`` runs the survivors again
(after a test was added for them).

Why not mutmut or cosmic-ray: numba's on-disk cache keys a compiled function by its own file only.
A function compiled in another module that inlines a mutated one (``pac_rig.loop.loop_tick``
inlines the controller's ``controller_step``) is loaded from the cache unchanged, so a mutant would
run the original code wherever it is called through another module: a false survivor.  And
mutmut's trampolines cannot run inside njit code.  Here each mutant gets its own cache directory,
a hard-linked copy of the warm one without the mutated module's entries and those of every module
that imports it (numba replaces cache files atomically, so the warm cache is never written).
"""

from __future__ import annotations

import argparse
import ast
import copy
import hashlib
import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FAST = "(unit or offline) and not live and not slow"
#: ``--slow``: a fast survivor again with the slow tests of its scope too, what `make test` adds
#: but live: the live tests drive the same cores through nodes (their physics is the offline
#: loop's, which the offline tests compare), at minutes a mutant.
FULL = "(unit or offline) and not live"
#: A fast survivor that a slow test kills.
KILLED_SLOW = "killed (slow)"

LINE_LAW_TESTS = (
    "tests/test_line_adaptive_properties.py",
    "tests/test_line_control.py",
    "tests/test_line_kernels.py",
    "tests/test_line_layout.py",
    "tests/test_line_map.py",
)
#: The FE line's behaviour: its own tests, the whole realistic line (stitch wires, slack droppers),
#: two pantographs on one line (several contacts in the active set) and the line files.
FE_TESTS = (
    "tests/test_catenary.py",
    "tests/test_line_physics.py",
    "tests/test_catenary_realistic.py",
    "tests/test_catenary_data.py",
    "tests/test_two_pantographs.py",
    "tests/test_offline_pantographs.py",
)
#: name -> (module, functions (qualified names), tests). The tests are those of the module's
#: behaviour that ``make test-fast`` runs; a mutant they all pass survives.
SCOPE: dict[str, tuple[str, tuple[str, ...], tuple[str, ...]]] = {
    "kernels": (
        "pac_controller.kernels",
        (
            "limit_command", "estimate_refused", "law_must_restart", "_limited", "law_command",
            "controller_fallback", "safety_chain", "law_mode", "fill_safety_chain", "new_state",
        ),
        ("tests/test_safety_chain.py", "tests/test_controller.py"),
    ),
    "controller": (
        "pac_controller.controller",
        (
            "watchdog_fallback_tick", "Controller.__init__", "Controller.last_u", "Controller.last_tick",
            "Controller.law_tick", "Controller.compute", "Controller.fallback", "Controller._command",
        ),
        ("tests/test_safety_chain.py", "tests/test_controller.py"),
    ),
    "watchdog": (
        "pac_controller.controller_node",
        ("ControllerNode.on_watchdog",),
        ("tests/test_safety_chain.py",),
    ),
    "guard": (
        "pac_controller.line_adaptive_kernels",
        ("_end_of_span",),
        LINE_LAW_TESTS,
    ),
    "line_law": (
        "pac_controller.line_adaptive_kernels",
        (
            "line_restart", "line_output", "line_commit", "_learn", "_step", "_fit_line", "_identified",
            "_model_response", "line_feedforward",
        ),
        LINE_LAW_TESTS,
    ),
    "contact_force": (
        "pac_observer.contact_force",
        ("frame_mass_scales", "contact_force_bank_step", "contact_force_advance", "ContactForceObserver"),
        ("tests/test_contact_force_bank.py", "tests/test_line_kernels.py", "tests/test_line_control.py"),
    ),
    "observer": (
        "pac_observer.observer",
        ("observer_advance", "observer_start"),
        ("tests/test_observer.py", "tests/test_compiled.py"),
    ),
    "head_balance": (
        "pac_observer.head_balance",
        ("_raw_force", "head_balance_start", "head_balance_advance", "_output"),
        ("tests/test_head_balance.py", "tests/test_fixed_gain_on_force.py"),
    ),
    "fe_step": (
        "pac_plant.catenary.step",
        ("hermite_weights", "fe_step"),
        FE_TESTS,
    ),
    "newmark": (
        "pac_plant.catenary.newmark",
        ("newmark_rhs", "newmark_update"),
        FE_TESTS,
    ),
    "banded": (
        "pac_plant.catenary.banded",
        ("band_chol_solve",),
        FE_TESTS,
    ),
    "bag_writer": (
        "pac_bag.mcap_writer",
        (
            "McapWriter.add_message", "McapWriter.add_messages", "McapWriter.flush_chunk",
            "McapWriter._message_indexes", "McapWriter.close", "message_records",
        ),
        ("tests/test_mcap_layout.py", "tests/test_bags.py", "tests/test_bag_damage.py"),
    ),
    "line": (
        "pac_plant.catenary.line",
        ("Line._assemble", "Line.solve_dropper_lengths", "Line.set_dropper_lengths", "Line._assemble_wires"),
        FE_TESTS,
    ),
}  # fmt: skip

#: Defects written by hand (scope -> (function, original text, replacement)): ones the operators
#: do not make, that got past the suite once.  Planted besides the generated mutants.
HAND_PLANTED: dict[str, tuple[tuple[str, str, str], ...]] = {
    "kernels": (
        ("controller_fallback", "_limited(p, s, tick, p.fallback_force)", "_limited(p, s, tick, f_r[0])"),
    ),
    "line": (
        (
            "Line._assemble",
            "mc, mm = d.clamp_mass_contact + half[j], d.clamp_mass_messenger + half[j]",
            "mc, mm = 2 * (d.clamp_mass_contact + half[j]), 2 * (d.clamp_mass_messenger + half[j])",
        ),
    ),
}

_COMPARE_SWAPS: dict[type, tuple[type, ...]] = {
    ast.Lt: (ast.LtE, ast.GtE),
    ast.LtE: (ast.Lt, ast.Gt),
    ast.Gt: (ast.GtE, ast.LtE),
    ast.GtE: (ast.Gt, ast.Lt),
    ast.Eq: (ast.NotEq,),
    ast.NotEq: (ast.Eq,),
}
_BINOP_SWAPS: dict[type, type] = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult}


@dataclass
class Mutant:
    """One planted defect: the source segment [start, end) (line, column; 1-based lines) replaced."""

    ident: str
    module: str
    function: str
    line: int
    original: str
    mutated: str
    start: tuple[int, int]
    end: tuple[int, int]
    status: str = "not run"  # killed, survived, timeout, not run, KILLED_SLOW
    seconds: float = 0.0
    failing: str = ""
    #: Run with the slow tests too (``--slow``): a survivor that has this survived ``make test``'s kinds.
    slow: bool = False
    #: What the mutant is, independent of where its function sits in the file: the function's name
    #: and a digest of its source, the change, and which occurrence of that change in the function.
    #: A result is kept while its key is the same (the function unchanged); lines may move.
    key: str = ""


def _functions(tree: ast.Module, names: tuple[str, ...]) -> list[tuple[str, ast.AST]]:
    """The (qualified name, node) of each function or class ``names`` lists."""
    found = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.ClassDef):
                name = f"{prefix}{child.name}"
                if name in names:
                    found.append((name, child))
                elif isinstance(child, ast.ClassDef):
                    visit(child, f"{name}.")

    visit(tree, "")
    missing = set(names) - {n for n, _ in found}
    if missing:
        raise SystemExit(f"mutation: not found in the module: {sorted(missing)}")
    return found


def _variants(node: ast.AST) -> list[ast.AST]:
    """The mutated copies of ``node`` itself (not of its children)."""
    out: list[ast.AST] = []
    if isinstance(node, ast.Compare) and len(node.ops) == 1:
        for op in _COMPARE_SWAPS.get(type(node.ops[0]), ()):
            m = copy.deepcopy(node)
            m.ops = [op()]
            out.append(m)
    elif isinstance(node, ast.BinOp) and type(node.op) in _BINOP_SWAPS:
        m = copy.deepcopy(node)
        m.op = _BINOP_SWAPS[type(node.op)]()
        out.append(m)
    elif isinstance(node, ast.BoolOp):
        m = copy.deepcopy(node)
        m.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
        out.append(m)
    elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not | ast.USub):
        out.append(copy.deepcopy(node.operand))
    elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("min", "max"):
        m = copy.deepcopy(node)
        m.func = ast.Name(id="max" if node.func.id == "min" else "min", ctx=ast.Load())
        out.append(m)
    elif isinstance(node, ast.Constant) and isinstance(node.value, bool):
        out.append(ast.Constant(value=not node.value))
    elif isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        v = node.value
        for new in {v + 1, 0 if v else 1, 2 * v if v not in (0, 1) else None} - {None, v}:
            out.append(ast.Constant(value=type(v)(new)))
    return out


def function_digest(source: str, fn: ast.AST) -> str:
    """A digest of a function's (or class's) source text: the same wherever it sits in the file."""
    return hashlib.sha256((ast.get_source_segment(source, fn) or "").encode()).hexdigest()[:12]


def mutants(module: str, functions: tuple[str, ...], source: str) -> list[Mutant]:
    """Every mutant of the listed functions, in source order; docstrings and annotations are skipped."""
    tree = ast.parse(source)
    out: list[Mutant] = []
    for name, fn in _functions(tree, functions):
        digest = function_digest(source, fn)
        skip: set[int] = set()
        for node in ast.walk(fn):
            if isinstance(node, ast.FunctionDef | ast.ClassDef):  # @njit(cache=True): not behaviour
                skip.update(id(n) for d in node.decorator_list for n in ast.walk(d))
            if isinstance(node, ast.FunctionDef | ast.ClassDef | ast.Module) and node.body:
                first = node.body[0]
                if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                    skip.add(id(first.value))
            if isinstance(node, ast.FunctionDef):
                for a in (*node.args.args, *node.args.kwonlyargs):
                    if a.annotation is not None:
                        skip.update(id(n) for n in ast.walk(a.annotation))
                if node.returns is not None:
                    skip.update(id(n) for n in ast.walk(node.returns))
            if isinstance(node, ast.AnnAssign):
                skip.update(id(n) for n in ast.walk(node.annotation))
            if isinstance(node, ast.Subscript):  # indices and dtype fields: out of range, not a defect
                skip.update(id(n) for n in ast.walk(node.slice) if isinstance(n, ast.Constant))
        for node in ast.walk(fn):
            if id(node) in skip or not hasattr(node, "lineno"):
                continue
            segment = ast.get_source_segment(source, node)
            if segment is None:
                continue
            for variant in _variants(node):
                text = ast.unparse(variant)
                if "\n" in segment:
                    continue
                index = sum(1 for m in out if m.line == node.lineno)
                change = f"{segment} -> ({text})"
                occurrence = sum(
                    1 for m in out if m.function == name and f"{m.original} -> {m.mutated}" == change
                )
                out.append(
                    Mutant(
                        ident=f"{module.rsplit('.', 1)[-1]}:{node.lineno}:{index}",
                        module=module,
                        function=name,
                        line=node.lineno,
                        original=segment,
                        mutated=f"({text})",
                        start=(node.lineno, node.col_offset),
                        end=(node.end_lineno or node.lineno, node.end_col_offset or 0),
                        key=f"{name}@{digest}: {change} #{occurrence}",
                    )
                )
    return out


def hand_planted(name: str, module: str, functions: tuple[str, ...], source: str) -> list[Mutant]:
    """The :data:`HAND_PLANTED` mutants of scope ``name``, located in ``source``."""
    tree = ast.parse(source)
    found = _functions(tree, functions)
    spans = {n: (f.lineno, f.end_lineno or f.lineno) for n, f in found}
    digests = {n: function_digest(source, f) for n, f in found}
    lines = source.splitlines()
    out = []
    for function, original, replacement in HAND_PLANTED.get(name, ()):
        first, last = spans[function]
        for i in range(first - 1, last):
            col = lines[i].find(original)
            if col >= 0:
                start = len(lines[i][:col].encode())
                end = start + len(original.encode())
                out.append(
                    Mutant(
                        f"{module.rsplit('.', 1)[-1]}:{i + 1}:hand", module, function, i + 1,
                        original, replacement, (i + 1, start), (i + 1, end),
                        key=f"{function}@{digests[function]}: {original} -> {replacement} #hand",
                    )
                )  # fmt: skip
                break
        else:
            raise SystemExit(f"mutation: {original!r} is not in {module}.{function}")
    return out


def apply(source: str, m: Mutant) -> str:
    lines = source.splitlines(keepends=True)
    (l0, c0), (l1, c1) = m.start, m.end
    assert l0 == l1
    line = lines[l0 - 1].encode()
    lines[l0 - 1] = (line[:c0] + m.mutated.encode() + line[c1:]).decode()
    return "".join(lines)


def _imports(path: Path, package: str) -> set[str]:
    """The project modules ``path`` (of ``package``) imports, as names (a.b.c and a.b.c.name)."""
    tree = ast.parse(path.read_text())
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
            mod = (f"{base}.{node.module}" if node.module else base) if node.level else node.module or ""
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return {m for m in out if m.startswith("pac_")}


def dependents(module: str) -> set[str]:
    """``module`` and every project module that imports it, directly or not (from src/)."""
    graph: dict[str, set[str]] = {}
    for path in (ROOT / "src").glob("*/pac_*/**/*.py"):
        parts = path.relative_to(ROOT / "src").with_suffix("").parts[1:]  # src/<package dir>/...
        if parts[-1] == "__init__":
            name = package = ".".join(parts[:-1])
        else:
            name, package = ".".join(parts), ".".join(parts[:-1])
        graph[name] = _imports(path, package)
    found, frontier = {module}, {module}
    while frontier:
        frontier = {m for m, deps in graph.items() if deps & frontier and m not in found}
        found |= frontier
    return found


def installed_file(module: str) -> Path:
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        raise SystemExit(f"mutation: {module} is not importable: run `make setup` and `source env.sh`")
    return Path(spec.origin)


def cache_for(modules: set[str], warm: Path, into: Path) -> None:
    """``into``: the warm numba cache, hard-linked, without the entries of ``modules``."""
    from numba.core.caching import _CacheLocator

    if into.exists():
        shutil.rmtree(into)
    shutil.copytree(warm, into, copy_function=os.link) if warm.exists() else into.mkdir(parents=True)
    for name in modules:
        try:
            origin = installed_file(name)
        except (SystemExit, ModuleNotFoundError):
            continue
        sub = into / _CacheLocator.get_suitable_cache_subpath(str(origin))
        stem = origin.stem
        for f in sub.glob(f"{stem}.*") if sub.exists() else ():
            f.unlink()


def fast_test_ids(tests: tuple[str, ...], env: dict) -> set[str]:
    """The node ids ``-m FAST`` selects of ``tests``: a test that kills in the slow stage but is
    among them (added after the fast stage ran) is a fast kill."""
    cmd = [sys.executable, "-m", "pytest", *tests, "-q", "--collect-only", "-p", "no:cacheprovider"]
    cmd += ["-m", FAST]
    out = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, check=True).stdout
    return {line.strip() for line in out.splitlines() if "::" in line}


def run_tests(tests: tuple[str, ...], env: dict, timeout: float, marks: str = FAST) -> tuple[str, str]:
    cmd = [sys.executable, "-m", "pytest", *tests, "-q", "-x", "-p", "no:cacheprovider", "-m", marks]
    proc = subprocess.Popen(
        cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return "timeout", ""
    except BaseException:  # the run stopped (SIGTERM, Ctrl-C): its tests, in their own session, too
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise
    if proc.returncode == 0:
        return "survived", ""
    failed = [
        line.split(" ", 1)[1].split(" - ")[0]
        for line in out.splitlines()
        if line.startswith(("FAILED", "ERROR"))
    ]
    if proc.returncode == 5:
        return "error", out[-2000:]
    return "killed", failed[0] if failed else f"pytest exit {proc.returncode}"


class Planted:
    """The installed file with a mutant in it; restored (text and times) on exit, whatever happens."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.backup = path.with_name(path.name + ".mutation-original")
        if self.backup.exists():  # an earlier run was killed before it restored the file
            shutil.copy2(self.backup, path)
        shutil.copy2(path, self.backup)
        self.original = path.read_text()
        self.stat = path.stat()

    def plant(self, text: str, serial: int) -> None:
        self.path.write_text(text)
        # A time of its own: Python's bytecode cache is keyed by the source's time and size.
        t = self.stat.st_mtime_ns + (serial + 1) * 1_000_000_000
        os.utime(self.path, ns=(t, t))

    def restore(self) -> None:
        shutil.copy2(self.backup, self.path)
        os.utime(self.path, ns=(self.stat.st_atime_ns, self.stat.st_mtime_ns))
        self.backup.unlink()


def load_notes(out: Path) -> dict[str, str]:
    path = out / "notes.json"
    return json.loads(path.read_text()) if path.exists() else {}


def note_for(m: Mutant, notes: dict[str, str]) -> str:
    """A survivor's argument, keyed by the mutant's ``key``: its function and a digest of the
    function's source, the change and its occurrence. A line move keeps it; any change to the
    function drops it with the result, since both must then be made again."""
    return notes.get(m.key, "")


def write_report(
    out: Path, name: str, tests: tuple[str, ...], ms: list[Mutant], notes: dict[str, str]
) -> None:
    done = [m for m in ms if m.status != "not run"]
    killed = sum(m.status in ("killed", "timeout") for m in done)
    slow = sum(m.status == KILLED_SLOW for m in done)
    lines = [
        f"# Mutation: {name} ({ms[0].module if ms else ''})",
        "",
        f'Tests (`-m "{FAST}"`; a survivor again with `-m "{FULL}"`): ' + ", ".join(f"`{t}`" for t in tests),
        "",
        f"{len(ms)} mutants, {len(done)} run: {killed} killed by the fast tests"
        + (f" ({100.0 * killed / len(done):.1f} %)" if done else "")
        + f", {slow} more by the slow ones"
        + (f" ({100.0 * (killed + slow) / len(done):.1f} % in all)" if done else "")
        + f", {sum(m.status == 'survived' for m in done)} survived, "
        f"{sum(m.status == 'timeout' for m in done)} of the killed by timeout.",
        "",
        "| id | function | line | original | mutant | result | caught by / why it survives |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in ms:
        caught = m.status in ("killed", KILLED_SLOW)
        why = m.failing if caught else note_for(m, notes) if m.status == "survived" else ""
        if m.status == "survived" and not why:
            why = "**not argued yet**"
        cells = [m.ident, f"`{m.function}`", str(m.line), f"`{m.original}`", f"`{m.mutated}`", m.status, why]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")
    (out / f"{name}.json").write_text(json.dumps([asdict(m) for m in ms], indent=1) + "\n")


def equivalent(record: dict, notes: dict[str, str]) -> bool:
    """A survivor argued equivalent: its note says so first (not near-equivalent, not a boundary)."""
    return notes.get(record.get("key", ""), "").startswith("Equivalent")


def write_summary(out: Path) -> None:
    notes = load_notes(out)
    rows = [
        "| scope | module | mutants | run | killed (fast) | killed (slow) | survived | score fast "
        "| score with slow | survivors run with slow | argued equivalent | score with slow, without them |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    total = [0, 0, 0, 0, 0, 0, 0]
    for name in SCOPE:
        path = out / f"{name}.json"
        if not path.exists():
            rows.append(f"| {name} | {SCOPE[name][0]} | | not run | | | | | | | | |")
            continue
        ms = json.loads(path.read_text())
        run = [m for m in ms if m["status"] != "not run"]
        killed = sum(m["status"] in ("killed", "timeout") for m in run)
        slow = sum(m["status"] == KILLED_SLOW for m in run)
        survived = sum(m["status"] == "survived" for m in run)
        same = sum(m["status"] == "survived" and equivalent(m, notes) for m in run)
        slow_run = sum(m["status"] == "survived" and m.get("slow", False) for m in run)
        counts = (len(ms), len(run), killed, slow, survived, slow_run, same)
        rows.append(_summary_row(f"[{name}]({name}.md)", SCOPE[name][0], counts))
        for i, v in enumerate(counts):
            total[i] += v
    rows.append(_summary_row("all", "", tuple(total)))
    text = [
        "# Mutation run (`make mutation`, scripts/mutation.py)",
        "",
        "Killed by the `make test-fast` kinds of each module's tests (listed per module); a timeout "
        'counts as killed. "killed (slow)": a fast survivor run again with the module\'s slow '
        f'tests too (`-m "{FULL}"`, `--slow`): what `make test` adds but live. "Survivors run with '
        'slow": how many of the survivors that stage ran (the others survived the fast tests only). '
        "Survivors are listed and argued in each module's page. "
        '"Argued equivalent": survivors whose argument (a judgement, each one written out) is that '
        "no input the rig accepts, or no state it reaches, tells them from the code; near-equivalents, "
        "boundaries of measure zero and gaps stay in the score without them.",
        "",
        *rows,
    ]
    (out / "summary.md").write_text("\n".join(text) + "\n")


def _summary_row(name: str, module: str, counts: tuple[int, ...]) -> str:
    mutants, run, killed, slow, survived, slow_run, same = counts
    cells = (
        name, module, mutants, run, killed, slow, survived, _percent(killed, run),
        _percent(killed + slow, run), slow_run, same, _percent(killed + slow, run - same),
    )  # fmt: skip
    return "| " + " | ".join(str(c) for c in cells) + " |"


def _percent(part: int, whole: int) -> str:
    return f"{100.0 * part / whole:.1f} %" if whole else ""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--modules", nargs="*", default=list(SCOPE), choices=list(SCOPE), help="scopes to run")
    ap.add_argument(
        "--timeout", type=float, default=900.0, help="per mutant [s] (a cold numba compile included)"
    )
    ap.add_argument("--list", action="store_true", help="list the mutants only")
    ap.add_argument("--only", nargs="*", default=None, help="mutant ids to run (default: all of the scopes)")
    ap.add_argument(
        "--survivors",
        action="store_true",
        help="run the survivors again (after tests were added), and what was not run",
    )
    ap.add_argument(
        "--slow",
        action="store_true",
        help="run the fast survivors again with the slow tests too (what make test adds but live)",
    )
    ap.add_argument("--out", type=Path, default=ROOT / "reports" / "mutation")
    args = ap.parse_args(argv)
    # A terminated run still restores the installed file (Planted.restore in a finally).
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    warm = Path(os.environ.get("NUMBA_CACHE_DIR", ROOT / "build" / "numba_cache"))
    args.out.mkdir(parents=True, exist_ok=True)
    notes = load_notes(args.out)
    import domain_coordinator

    with domain_coordinator.domain_id() as did, tempfile.TemporaryDirectory(prefix="pac-mutation-") as tmp:
        env = dict(
            os.environ, ROS_DOMAIN_ID=str(did), PAC_ROS_DOMAIN_ID_BASE=str(did),
            ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", PYTHONDONTWRITEBYTECODE="1",
        )  # fmt: skip
        for name in args.modules:
            module, functions, tests = SCOPE[name]
            path = installed_file(module)
            source = path.read_text()
            ms = mutants(module, functions, source) + hand_planted(name, module, functions, source)
            if args.list:
                for m in ms:
                    print(f"{m.ident:28} {m.function:28} {m.original!r} -> {m.mutated!r}")
                continue
            results = args.out / f"{name}.json"
            previous = (
                {m.get("key") or m["ident"]: m for m in json.loads(results.read_text())}
                if results.exists()
                else {}
            )
            for m in ms:  # keep the results of mutants not run this time, while their function is unchanged
                old = previous.get(m.key)
                if old and old["original"] == m.original and old["mutated"] == m.mutated:
                    m.status, m.seconds, m.failing = old["status"], old["seconds"], old["failing"]
                    m.slow = old.get("slow", False)
            stale = dependents(module)
            fast_ids = fast_test_ids(tests, env) if args.slow else set()
            planted = Planted(path)
            try:
                for serial, m in enumerate(ms):
                    if args.only is not None and m.ident not in args.only:
                        continue
                    if args.slow and m.status != "survived":
                        continue  # (a fast survivor only: the slow stage runs after the fast one)
                    if (
                        not args.slow
                        and args.only is None
                        and m.status != "not run"
                        and not (args.survivors and m.status in ("survived", KILLED_SLOW))
                    ):
                        continue
                    planted.plant(apply(source, m), serial)
                    cache = Path(tmp) / "numba_cache"
                    cache_for(stale, warm, cache)
                    t0 = time.monotonic()
                    status, m.failing = run_tests(
                        tests,
                        {**env, "NUMBA_CACHE_DIR": str(cache)},
                        args.timeout,
                        FULL if args.slow else FAST,
                    )
                    # In the slow stage a kill by a test of the fast selection (added since) is a fast kill.
                    fast_kill = status == "killed" and m.failing in fast_ids
                    if args.slow and status in ("killed", "timeout") and not fast_kill:
                        status = KILLED_SLOW
                    m.status = status
                    m.slow = m.slow or args.slow  # (a fast run after a slow one adds fast tests only)
                    m.seconds = round(time.monotonic() - t0, 1)
                    planted.path.write_text(source)
                    print(
                        f"{m.ident:28} {m.status:9} {m.seconds:6.1f} s  {m.original!r} -> {m.mutated!r}",
                        flush=True,
                    )
                    write_report(args.out, name, tests, ms, notes)
            finally:
                planted.restore()
            write_report(args.out, name, tests, ms, notes)
        if not args.list:
            write_summary(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
