"""``ros2 pkg list | executables [<package>] | prefix <package>`` from the ament index."""

from __future__ import annotations

from .common import executables, fail, index, package_prefix


def pkg_list(args: list[str]) -> int:
    for name in sorted(index().get_packages_with_prefixes()):
        print(name)
    return 0


def pkg_executables(args: list[str]) -> int:
    for pkg in args[:1] or sorted(index().get_packages_with_prefixes()):
        for exe in executables(pkg):
            print(f"{pkg} {exe}")
    return 0


def pkg_prefix(args: list[str]) -> int:
    if len(args) != 1:
        fail("expected pkg prefix <package>", 2)
    print(package_prefix(args[0]))
    return 0
