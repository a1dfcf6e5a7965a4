"""``ros2 run``: resolve <prefix>/lib/<package>/<executable> through the ament index and exec it.

exec() in place, as ros2cli does, so the node keeps this process's PID and receives signals
directly.
"""

from __future__ import annotations

import os
import shlex

from .common import executables, fail, package_prefix


def run(args: list[str]) -> int:
    prefix: list[str] = []
    while args and args[0].startswith("--prefix"):
        if args[0] == "--prefix" and len(args) > 1:
            prefix, args = shlex.split(args[1]), args[2:]
        elif args[0].startswith("--prefix="):
            prefix, args = shlex.split(args[0].split("=", 1)[1]), args[1:]
        else:
            fail("--prefix needs a command", 2)
    if len(args) < 2:
        fail("expected run [--prefix CMD] <package> <executable> [args...]", 2)
    pkg, exe, rest = args[0], args[1], args[2:]
    path = os.path.join(package_prefix(pkg), "lib", pkg, exe)
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        known = ", ".join(executables(pkg)) or "none"
        fail(f"no executable '{exe}' in package '{pkg}' (available: {known})")
    argv = [*prefix, path, *rest]
    try:
        if prefix:
            os.execvp(argv[0], argv)
        os.execv(path, argv)
    except OSError as exc:
        fail(f"cannot execute {argv[0]}: {exc}")
    return 1  # not reached
