"""Bad input to the files, parameters, output paths and campaigns: one line, the right exit
status, no hang, nothing half-written (docs/design.md, 'Inputs and their limits')."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from pac_analysis import report
from pac_common.command_line import ParamsFile, UsageError
from pac_common.files import (
    MAX_DEPTH,
    MAX_INTEGER_DIGITS,
    FileInputError,
    load_yaml,
    read_text,
    read_yaml,
    write_atomic,
)
from pac_common.parameters import ParameterError, check_output_folder
from pac_experiments.campaign import cli as campaign
from pac_experiments.campaign import dask_runner as campaign_dask
from pac_experiments.campaign import results as campaign_results
from pac_experiments.campaign import spec as campaign_spec
from pac_model.pantograph_file import load_pantograph_file
from pac_plant.catenary.catenary_file import load_catenary
from pac_rig import simulate
from pac_rig.cli import OverrideError, load_params_file, parse_overrides

pytestmark = pytest.mark.offline

#: An alias bomb: nine levels, each nine aliases of the one before (9**9 items when expanded).
ALIAS_BOMB = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]\n" for i in range(1, 10)
)
SPEC = "grid:\n  c1: [20.0]\nfixed:\n  duration: 0.5\nwindow: [0.25, 0.5]\n"
ROS_PARAMS = "/**:\n  ros__parameters:\n    c1: 20.0\n"


def returns_within(seconds: float, call: Callable[[], Any]) -> Any:
    """``call()``'s result or exception, failing the test if it has not returned in ``seconds``
    (a FIFO opened for reading blocks until a writer comes; the thread is then left blocked,
    so the FIFO is opened once for writing to release it)."""
    outcome: dict[str, Any] = {}

    def run() -> None:
        try:
            outcome["value"] = call()
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            outcome["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"still blocked after {seconds} s"
    if "error" in outcome:
        raise outcome["error"]
    return outcome.get("value")


@pytest.fixture
def fifo(tmp_path: Path) -> Iterator[Path]:
    path = tmp_path / "fifo.yaml"
    os.mkfifo(path)
    yield path
    # A reader still blocked on it (the old code) is released by a writer that opens and closes.
    with contextlib.suppress(OSError):
        os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))


def one_line_error(capsys: pytest.CaptureFixture[str], status: int, code: int, *needles: str) -> str:
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == code and len(lines) == 1 and "Traceback" not in err, (status, err)
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


# -- 2. FIFOs, devices and directories: refused before they are opened --------------------------
@pytest.mark.unit
@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
def test_read_refuses_what_is_not_a_regular_file(kind: str, fifo: Path, tmp_path: Path) -> None:
    path = {"fifo": fifo, "device": Path("/dev/zero"), "directory": tmp_path}[kind]
    with pytest.raises(FileInputError, match="allowed a regular file") as caught:
        returns_within(5.0, lambda: read_text(path, "params"))
    assert {"fifo": "a FIFO", "device": "a device", "directory": "a directory"}[kind] in str(caught.value)


@pytest.mark.unit
def test_every_file_input_refuses_a_fifo_at_once(fifo: Path, tmp_path: Path) -> None:
    """The node's --params-file, the tools' --params-file, catenary:=, pantograph:= (and
    nominal_pantograph:=, the same reader), a SPEC and a SPEC's catenary: none blocks."""
    readers: list[tuple[Callable[[], Any], type[Exception]]] = [
        (lambda: ParamsFile.read(str(fifo)), UsageError),
        (lambda: load_params_file(fifo), OverrideError),
        (lambda: load_catenary(str(fifo)), ParameterError),
        (lambda: load_pantograph_file(str(fifo)), ParameterError),
        (lambda: campaign_spec.load_spec(fifo), campaign_spec.SpecError),
    ]
    spec = tmp_path / "spec.yaml"
    spec.write_text(
        f"grid:\n  c1: [20.0]\nfixed:\n  catenary_model: fe\n  catenary: {fifo}\n  duration: 0.5\n"
    )
    readers.append((lambda: campaign_spec.load_points(spec), campaign_spec.SpecError))
    for read, error in readers:
        with pytest.raises(error, match="FIFO"):
            returns_within(5.0, read)


@pytest.mark.unit
def test_a_device_is_not_read_to_the_end(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """``-p pantograph:=/dev/zero`` grew to gigabytes; now refused before a byte is read."""
    status = returns_within(
        30.0, lambda: simulate.main([str(tmp_path / "bag"), "-p", "pantograph:=/dev/zero"])
    )
    one_line_error(capsys, status, 2, "pantograph", "a device")


@pytest.mark.unit
def test_a_file_over_its_kinds_cap_is_refused(tmp_path: Path) -> None:
    big = tmp_path / "big.yaml"
    big.write_text("# padding\n" * 30_000)  # 300 kB of comments: valid YAML, over 256 KiB
    with pytest.raises(FileInputError, match="larger than 262144 bytes"):
        read_yaml(big, "params")


# -- 3. aliases: refused, never expanded into a message -------------------------------------------
@pytest.mark.unit
def test_an_alias_bomb_is_refused_everywhere_with_a_short_line(tmp_path: Path) -> None:
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(ALIAS_BOMB)
    params = tmp_path / "params.yaml"
    params.write_text(
        "/**:\n  ros__parameters:\n" + "".join("    " + line + "\n" for line in ALIAS_BOMB.splitlines())
    )
    spec = tmp_path / "spec.yaml"
    spec.write_text(SPEC + "unknown:\n" + "".join("  " + line + "\n" for line in ALIAS_BOMB.splitlines()))
    calls: list[Callable[[], Any]] = [
        lambda: ParamsFile.read(str(params)),
        lambda: load_params_file(params),
        lambda: load_catenary(str(bomb)),
        lambda: load_pantograph_file(str(bomb)),
        lambda: campaign_spec.load_spec(spec),
        lambda: parse_overrides([f"c1:={{{ALIAS_BOMB.replace(chr(10), ', ')}}}"]),
    ]
    for call in calls:
        with pytest.raises(ValueError, match="alias") as caught:
            returns_within(10.0, call)
        assert len(str(caught.value)) < 600 and "\n" not in str(caught.value), str(caught.value)[:900]


@pytest.mark.unit
def test_a_message_quotes_a_short_prefix_of_a_file(tmp_path: Path) -> None:
    """A SPEC's catenary naming a text file that is not YAML (as /etc/passwd): its content is
    quoted at most by a short prefix."""
    text_file = tmp_path / "passwd"
    text_file.write_text("".join(f"user{i}:x:{i}:{i}::/home/user{i}:/bin/sh\n" for i in range(500)))
    spec = tmp_path / "spec.yaml"
    spec.write_text(
        f"grid:\n  c1: [20.0]\nfixed:\n  catenary_model: fe\n  catenary: {text_file}\n  duration: 0.5\n"
    )
    with pytest.raises(campaign_spec.SpecError) as caught:
        campaign_spec.load_points(spec)
    assert "user0" in str(caught.value) and "user20:" not in str(caught.value), str(caught.value)[:900]
    assert len(str(caught.value)) < 800


# -- 4. simulate's compression ----------------------------------------------------------------------
@pytest.mark.parametrize("compression", ["none", "lz4", "zstd"])
def test_simulate_writes_the_compression_asked_for(compression: str, tmp_path: Path) -> None:
    import gc

    from mcap.reader import make_reader

    bag = tmp_path / "bag"
    frozen = gc.get_freeze_count()
    assert simulate.main([str(bag), "-p", "duration:=0.05", "-p", f"compression:={compression}"]) == 0
    assert gc.get_freeze_count() == frozen  # what simulate froze for its run is thawed again
    with open(bag / "bag.mcap", "rb") as stream:
        chunks = {c.compression for c in make_reader(stream).get_summary().chunk_indexes}
    assert chunks == {"" if compression == "none" else compression}


@pytest.mark.unit
def test_simulate_refuses_an_unknown_compression(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    status = simulate.main([str(tmp_path / "bag"), "-p", "compression:=gzip"])
    one_line_error(capsys, status, 2, "compression", "gzip", "zstd, lz4, none")
    assert not (tmp_path / "bag").exists()


# -- 6. malformed YAML and text: one line, no traceback ---------------------------------------------
MALFORMED = {
    "deep nesting": "a: " + "[" * 5000 + "]" * 5000,
    "nesting past the limit": "a: " + "[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1),
    "unhashable key": "? [1, 2]\n: 3\n",
    "mapping key": "{a: 1}: 3\n",
    "long integer": "a: " + "9" * 5000,
    "integer past the limit": "a: " + "9" * (MAX_INTEGER_DIGITS + 1),
    "duplicate key": "a: 1\na: 2\n",
    "python tag": "a: !!python/object/apply:os.system [echo]\n",
}


@pytest.mark.unit
@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_yaml_is_one_line(case: str) -> None:
    with pytest.raises(FileInputError) as caught:
        load_yaml(MALFORMED[case], "test")
    message = str(caught.value)
    assert "\n" not in message and len(message) < 300, message[:500]


@pytest.mark.unit
def test_the_limits_are_the_limits() -> None:
    """At the limits a document is read (the refusals above are the limits, not any nesting)."""
    depth = MAX_DEPTH - 1  # the top-level mapping is one level
    assert load_yaml("a: " + "[" * depth + "]" * depth, "test")
    assert load_yaml("a: " + "9" * MAX_INTEGER_DIGITS, "test") == {"a": int("9" * MAX_INTEGER_DIGITS)}


@pytest.mark.unit
def test_every_yaml_input_refuses_non_utf8_and_a_nul_in_the_path(tmp_path: Path) -> None:
    latin = tmp_path / "latin.yaml"
    latin.write_bytes(b"/**:\n  ros__parameters:\n    name: caf\xe9\n")
    for call, error in [
        (lambda: ParamsFile.read(str(latin)), UsageError),
        (lambda: load_params_file(latin), OverrideError),
        (lambda: campaign_spec.load_spec(latin), campaign_spec.SpecError),
        (lambda: load_catenary(str(latin)), ParameterError),
    ]:
        with pytest.raises(error, match=r"not UTF-8 text \(byte 0xe9 at offset 37\)"):
            call()
    with pytest.raises(UsageError, match="NUL|null"):
        ParamsFile.read(str(tmp_path) + "/a\0b.yaml")
    with pytest.raises(ParameterError, match="NUL"):
        check_output_folder("--out", Path(str(tmp_path) + "/a\0b"))


@pytest.mark.unit
def test_damaged_runs_lines_are_named_and_skipped(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    good = '{"key": "abc", "status": "ok", "sigma_f": null}'
    lines = [good, '{"key": [1, 2]}', b"\xff\xfe".decode("latin-1"), "[" * 100_000, "{}", '{"key": "tor']
    (tmp_path / campaign_results.RUNS_FILE).write_bytes("\n".join(lines).encode("latin-1"))
    done = campaign_results.read_done(tmp_path)
    assert list(done) == ["abc"]
    err = capsys.readouterr().err
    assert "4 line(s) are no run row" in err and "first: line 2" in err and "Traceback" not in err


# -- 7. output paths: checked before the work, never half-written -------------------------------------
@pytest.mark.unit
def test_campaign_out_that_is_a_file_stops_before_any_run(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    out.write_text("keep me")
    status = campaign.main([str(spec), "--out", str(out)])
    one_line_error(capsys, status, 2, "--out", "a folder (this is a file)")
    assert out.read_text() == "keep me"


@contextlib.contextmanager
def tiny_tmpfs(folder: Path, size: str = "64k") -> Iterator[Path]:
    """A small tmpfs mounted on ``folder`` for the test (root only), unmounted afterwards."""
    folder.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


def fill(folder: Path) -> None:
    """Fill the file system of ``folder`` up to its last byte."""
    with contextlib.suppress(OSError), open(folder / "filler", "wb", buffering=0) as f:
        while True:
            f.write(bytes(4096))


@pytest.mark.unit
def test_a_full_disk_is_refused_before_the_work(tmp_path: Path) -> None:
    """An empty file can still be created on a full disk: the check writes data."""
    with tiny_tmpfs(tmp_path / "disk") as disk:
        fill(disk)
        with pytest.raises(ParameterError, match="writable"):
            check_output_folder("--out", disk / "campaign")
        with pytest.raises(ParameterError, match="write in"):
            check_output_folder("--out", disk)


@pytest.mark.unit
def test_write_atomic_leaves_the_old_file_on_a_full_disk(tmp_path: Path) -> None:
    with tiny_tmpfs(tmp_path / "disk") as disk:
        target = disk / "results.csv"
        target.write_text("old\n")
        fill(disk)
        with pytest.raises(OSError), write_atomic(target) as handle:
            handle.write("new\n" * 100_000)
        assert target.read_text() == "old\n"
        assert sorted(p.name for p in disk.iterdir()) == ["filler", "results.csv"]


def test_simulate_on_a_disk_that_fills_up_removes_its_bag(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    with tiny_tmpfs(tmp_path / "disk", "256k") as disk:
        bag = disk / "bag"
        status = simulate.main([str(bag), "-p", "duration:=30.0", "-p", "compression:=none"])
        one_line_error(capsys, status, 1, "No space left on device", "the incomplete bag was removed")
        assert not bag.exists()


def test_campaign_on_a_disk_that_fills_up_says_so(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """runs.jsonl cannot be appended to: one line, exit 1, the rows written before are kept."""
    spec = tmp_path / "spec.yaml"
    spec.write_text("grid:\n  c1: [20.0, 30.0, 40.0]\nfixed:\n  duration: 0.5\nwindow: [0.25, 0.5]\n")
    with tiny_tmpfs(tmp_path / "disk") as disk:
        out = disk / "out"
        out.mkdir()
        (out / campaign_results.RUNS_FILE).write_text("")
        real_rows = campaign_dask._RowLog.rows

        def rows_then_full(self: Any, rows: list[dict]) -> None:
            real_rows(self, rows)
            fill(disk)  # the disk fills up after the first chunk's rows

        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(campaign_dask._RowLog, "rows", rows_then_full)
            status = campaign.main([str(spec), "--out", str(out), "--chunk-size", "1", "--no-report"])
        err = capsys.readouterr().err
        lines = [line for line in err.splitlines() if line.strip()]
        assert status == 1 and len(lines) == 1 and "No space left on device" in lines[0], err
        assert "re-run the same command to resume" in lines[0]
        assert len(campaign_results.read_done(out)) == 1


# -- 8. a params file: the rig's nodes' sections and /**, nothing else --------------------------------
@pytest.mark.unit
def test_simulate_params_file_takes_only_the_rigs_sections(tmp_path: Path) -> None:
    path = tmp_path / "params.yaml"
    path.write_text(
        "/**:\n  ros__parameters:\n    c2: 35.0\n"
        "controller_node:\n  ros__parameters:\n    c1: 30.0\n"
        "some_other_node:\n  ros__parameters:\n    c1: 50.0\n    c3: 99.0\n"
    )
    assert load_params_file(path) == {"c2": 35.0, "c1": 30.0}


# -- 11. campaign grids: a cap, a line before the work, Ctrl-C ----------------------------------------
@pytest.mark.unit
def test_a_grid_over_the_cap_is_refused_at_once(tmp_path: Path) -> None:
    spec = tmp_path / "spec.yaml"
    values = ", ".join(str(20.0 + i) for i in range(100))
    spec.write_text(
        f"grid:\n  c1: [{values}]\n  c2: [{values}]\n  c3: [{values}]\n  c4: [{values}]\nwindow: [0.1, 0.2]\n"
    )
    with pytest.raises(campaign_spec.SpecError, match="100000000 points: allowed at most 10000"):
        returns_within(10.0, lambda: campaign_spec.load_points(spec))


@pytest.mark.unit
def test_campaign_says_its_size_before_checking_and_stops_on_ctrl_c(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    spec = tmp_path / "spec.yaml"
    speeds = ", ".join(str(100.0 + i) for i in range(campaign.ANNOUNCE_POINTS))
    spec.write_text(SPEC.replace("c1: [20.0]", f"c1: [20.0]\n  speed_kmh: [{speeds}]"))

    def interrupted(spec: campaign_spec.Spec) -> list[campaign_spec.Point]:
        said = f"campaign spec: {campaign.ANNOUNCE_POINTS} grid points in 1 grid(s); checking them"
        assert said in capsys.readouterr().out
        raise KeyboardInterrupt

    monkeypatch.setattr(campaign_spec, "expand", interrupted)
    status = campaign.main([str(spec), "--out", str(tmp_path / "out")])
    one_line_error(capsys, status, 130, "interrupted")


# -- 12. duplicate keys, list parameters, 1e4, report's window ---------------------------------------
@pytest.mark.unit
def test_duplicate_keys_are_refused_in_params_files_and_spec_grids(tmp_path: Path) -> None:
    params = tmp_path / "params.yaml"
    params.write_text("/**:\n  ros__parameters:\n    c1: 20.0\n    c1: 30.0\n")
    with pytest.raises(UsageError, match="'c1' given twice"):
        ParamsFile.read(str(params))
    with pytest.raises(OverrideError, match="'c1' given twice"):
        load_params_file(params)
    spec = tmp_path / "spec.yaml"
    spec.write_text("grid:\n  c1: [20.0]\n  c1: [30.0]\nwindow: [0.25, 0.5]\n")
    with pytest.raises(campaign_spec.SpecError, match="'c1' given twice"):
        campaign_spec.load_spec(spec)


@pytest.mark.unit
@pytest.mark.parametrize("value", ["'00'", "[true, true]", "[1, '2']"])
def test_list_parameters_refuse_strings_and_booleans(value: str) -> None:
    with pytest.raises(ParameterError, match="noise_std"):
        simulate.scenario_from_flat(parse_overrides([f"noise_std:={value}"]))


@pytest.mark.unit
@pytest.mark.parametrize(("text", "number"), [("1e4", 1e4), ("-2.5E-3", -2.5e-3), ("+3e+2", 300.0)])
def test_exponent_without_a_dot_is_a_number_as_for_the_nodes(text: str, number: float) -> None:
    assert parse_overrides([f"k1:={text}"]) == {"k1": number}


@pytest.mark.unit
def test_simulate_takes_k1_1e4() -> None:
    assert simulate.scenario_from_flat(parse_overrides(["k1:=1e4"])).pantograph.k1 == 1e4


@pytest.mark.unit
@pytest.mark.parametrize("window", [["--from", "nan"], ["--from", "0.9", "--to", "0.1"], ["--to", "inf"]])
def test_report_refuses_a_bad_window_with_status_2(
    window: list[str], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    with pytest.raises(SystemExit) as caught:
        report.main([str(tmp_path / "no_bag"), *window, "--out", str(tmp_path / "out")])
    assert caught.value.code == 2
    assert "Traceback" not in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.unit
def test_yaml_keeps_what_yaml_11_reads() -> None:
    """The loader changes nothing else: strings, booleans, floats with a dot, ints."""
    assert load_yaml("a: [1.0, 2, 'x', true, ~, 1_000, 0x10, .5]", "t") == {
        "a": [1.0, 2, "x", True, None, 1000, 16, 0.5]
    }
    assert yaml.safe_load("a: 1e4") == {"a": "1e4"}  # what PyYAML alone reads (the old refusal)


# -- the node processes: a FIFO params file and rcl's own refusal ------------------------------------
def run_node(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pac_controller.controller_node", "--ros-args", *args],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"},
    )


@pytest.mark.slow
def test_a_node_refuses_a_fifo_params_file_at_once(fifo: Path) -> None:
    """It blocked on the open, deaf to SIGINT and SIGTERM."""
    run = run_node("--params-file", str(fifo))
    assert run.returncode == 2 and "a FIFO: allowed a regular file" in run.stderr, run.stderr
    assert len(run.stderr.strip().splitlines()) == 1, run.stderr


@pytest.mark.slow
def test_rcls_refusal_is_pacs_one_line(tmp_path: Path) -> None:
    """A params file rcl refuses (a list of mixed types): pac's line only, not rcl's [ERROR] first."""
    params = tmp_path / "params.yaml"
    params.write_text("/**:\n  ros__parameters:\n    c1: [1, 'a']\n")
    run = run_node("--params-file", str(params))
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("controller_node: cannot start:"), run.stderr
    assert "Sequence should be of same type" in lines[0] and "[ERROR]" not in run.stderr


@pytest.mark.unit
def test_a_pantograph_too_stiff_for_the_sample_period_is_refused_without_warnings(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A tiny mass: numpy's and scipy's RuntimeWarnings came first, then a run diverged at tick 1."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for mass in ("1e-6", "1e-300"):
            status = simulate.main([str(tmp_path / "bag"), "-p", f"m1:={mass}", "-p", "duration:=0.2"])
            one_line_error(capsys, status, 2, "'pantograph'", f"m1={float(mass):g} kg", "sample period")
