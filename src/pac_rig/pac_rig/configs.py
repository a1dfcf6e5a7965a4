"""The default parameter files shipped in each package's ``config/`` (share/<pkg>/config/).

They are generated from the parameter declarations, so they cannot drift:
``python -m pac_rig.configs --write`` rewrites them, the tests check them.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from .nodes import NODES


def parameter_sets(node: str) -> list:
    """The parameter sets a node (a role of :data:`pac_rig.nodes.NODES`) declares."""
    return NODES[node].parameter_sets()


def defaults_yaml(node: str) -> str:
    """The shipped ``config/<executable>.yaml`` of a node (a role of :data:`pac_rig.nodes.NODES`)."""
    package, executable = NODES[node].package, NODES[node].executable
    sets = parameter_sets(node)
    lines = [
        f"# Defaults of {package}/{executable} (Table 1, 360 km/h, the shipped gains).",
        "# Generated from the parameter declarations: python -m pac_rig.configs --write",
        f"# Use: ros2 run {package} {executable} --ros-args --params-file <this file>",
        "/**:",
        "  ros__parameters:",
    ]
    for cls in sets:
        lines.append(f"    # {cls.__name__}")
        for spec in cls.specs():
            value = list(spec.default) if isinstance(spec.default, tuple) else spec.default
            text = yaml.safe_dump(value, default_flow_style=True).strip().removesuffix("\n...").strip()
            unit = f" [{spec.unit}]" if spec.unit else ""
            when = "; may change at run time" if spec.runtime else ""
            comment = f"{spec.description}{unit}; allowed {spec.allowed(registry_names=False)}{when}"
            lines.append(f"    {spec.name}: {text}  # {comment}")
    return "\n".join(lines) + "\n"


def config_path(node: str, src: Path) -> Path:
    """The file in a source tree (``src`` is the workspace's src/ folder)."""
    entry = NODES[node]
    return src / entry.package / "config" / f"{entry.executable}.yaml"


def installed_config_path(node: str) -> Path:
    from ament_index_python.packages import get_package_share_directory

    entry = NODES[node]
    return Path(get_package_share_directory(entry.package)) / "config" / f"{entry.executable}.yaml"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="configs", description=__doc__)
    parser.add_argument("--write", action="store_true", help="rewrite <src>/<pkg>/config/<node>.yaml")
    parser.add_argument("--src", type=Path, default=Path("src"), help="the workspace's src/ folder")
    args = parser.parse_args(argv)
    for node in NODES:
        text = defaults_yaml(node)
        if args.write:
            config_path(node, args.src).write_text(text)
            print(f"wrote {config_path(node, args.src)}")
        else:
            print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
