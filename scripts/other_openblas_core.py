"""Print an OpenBLAS core type other than the one numpy's OpenBLAS chose on this machine, which this
CPU can run, for ``make test-portable`` (``OPENBLAS_CORETYPE``; docs/numerics.md, "Tests that pass on
any machine"). OpenBLAS picks its kernels (dot products, matrix products, solves) by CPU, so the
same call rounds differently on another CPU; a test that holds only with this machine's kernels
fails with another's. The first of Haswell (AVX2 and FMA: the kernels OpenBLAS gives AMD's Zen),
Sandybridge (AVX), Nehalem (SSE4.2) that the CPU has and OpenBLAS did not choose; nothing (the
machine's own choice) where none is, or off x86-64.
"""

from __future__ import annotations

import ctypes
import glob
import os
import platform
from pathlib import Path

import numpy as np

#: The getter of the core type, by the names numpy's and other OpenBLAS builds export it under.
GETTERS = ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename")
#: Core types to try, each with the CPU flags (/proc/cpuinfo) its kernels use.
CANDIDATES = (("Haswell", {"avx2", "fma"}), ("Sandybridge", {"avx"}), ("Nehalem", {"sse4_2"}))


def chosen_core() -> str | None:
    """The core type numpy's bundled OpenBLAS runs on (None: not found)."""
    libs = Path(np.__file__).parent.parent / "numpy.libs"
    for path in glob.glob(str(libs / "*openblas*.so*")):
        lib = ctypes.CDLL(path)
        for symbol in GETTERS:
            if hasattr(lib, symbol):
                getter = getattr(lib, symbol)
                getter.restype = ctypes.c_char_p
                return str(getter().decode())
    return None


def cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    line = next((row for row in text.splitlines() if row.startswith("flags")), "")
    return set(line.partition(":")[2].split())


def main() -> None:
    if platform.machine() not in ("x86_64", "AMD64"):
        return
    chosen = os.environ.get("OPENBLAS_CORETYPE") or chosen_core()
    flags = cpu_flags()
    for core, needs in CANDIDATES:
        if needs <= flags and (chosen or "").lower() != core.lower():
            print(core)
            return


if __name__ == "__main__":
    main()
