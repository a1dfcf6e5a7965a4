"""``ros2 interface list | package | show`` from the ament index and the installed .msg files."""

from __future__ import annotations

import os

from .common import fail, index, parser, split_type

PRIMITIVES = frozenset(
    {
        "bool",
        "byte",
        "char",
        "float32",
        "float64",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "string",
        "wstring",
    }
)


def interfaces() -> dict[str, list[str]]:
    """package -> ['msg/Name', ...] from the ament index (what ros2cli lists)."""
    aip = index()
    out = {}
    for pkg in sorted(aip.get_resources("rosidl_interfaces")):
        content, _ = aip.get_resource("rosidl_interfaces", pkg)
        out[pkg] = sorted(
            {
                line.rsplit(".", 1)[0]
                for line in content.splitlines()
                if line.endswith((".msg", ".srv", ".action"))
            }
        )
    return out


def interface_text(typename: str) -> str:
    pkg, kind, name = split_type(typename)
    aip = index()
    try:
        share = aip.get_package_share_directory(pkg)
    except aip.PackageNotFoundError:
        fail(f"unknown package '{pkg}'")
    path = os.path.join(share, kind, f"{name}.{kind}")
    if not os.path.isfile(path):
        fail(f"unknown interface '{typename}' (ros2 interface package {pkg} lists them)")
    with open(path, encoding="utf-8") as f:
        return f.read()


def show_lines(typename: str, depth: int, all_comments: bool, no_comments: bool, out: list[str]) -> None:
    """ros2cli's layout: the definition as written, nested types expanded one tab deeper;
    nested comments only with --all-comments."""
    pkg = typename.split("/")[0]
    keep_comments = not no_comments and (depth == 0 or all_comments)
    for line in interface_text(typename).splitlines():
        code = line.split("#", 1)[0].rstrip()
        if not code:
            if keep_comments and (line.strip() or depth == 0):
                out.append("\t" * depth + line)
            continue
        out.append("\t" * depth + (line if keep_comments else code))
        if "=" in code.split()[-1] or len(code.split()) < 2:
            continue  # a constant
        base = code.split()[0].split("[")[0].split("<=")[0]
        if base in PRIMITIVES:
            continue
        nested = base if "/" in base else f"{pkg}/{base}"
        show_lines(nested, depth + 1, all_comments, no_comments, out)


def interface_list(args: list[str]) -> int:
    for pkg, names in interfaces().items():
        for n in names:
            print(f"    {pkg}/{n}")
    return 0


def interface_package(args: list[str]) -> int:
    if len(args) != 1:
        fail("expected interface package <package>", 2)
    names = interfaces().get(args[0])
    if names is None:
        fail(f"unknown package '{args[0]}'")
    for n in names:
        print(f"{args[0]}/{n}")
    return 0


def interface_show(args: list[str]) -> int:
    p = parser("interface show")
    p.add_argument("type", help="e.g. pac_interfaces/msg/FrameMeasurement")
    p.add_argument("--all-comments", action="store_true", help="also the nested types' comments")
    p.add_argument("--no-comments", action="store_true")
    a = p.parse_args(args)
    out: list[str] = []
    show_lines(a.type, 0, a.all_comments, a.no_comments, out)
    print("\n".join(out))
    return 0
