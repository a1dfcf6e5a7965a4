"""QoS profiles as rosbag2 v9 records them (``offered_qos_profiles``), and the YAML it writes them in."""

from __future__ import annotations

from typing import Any


def _duration(value: Any) -> dict[str, int]:
    ns = int(getattr(value, "nanoseconds", value))
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def qos_dict(profile: Any) -> dict[str, Any]:
    """A QoS profile (rclpy ``QoSProfile``, e.g. from ``get_publishers_info_by_topic``) as
    rosbag2 v9 writes it in ``offered_qos_profiles``."""
    return {
        "history": profile.history.name.lower(),
        "depth": int(profile.depth),
        "reliability": profile.reliability.name.lower(),
        "durability": profile.durability.name.lower(),
        "deadline": _duration(profile.deadline),
        "lifespan": _duration(profile.lifespan),
        "liveliness": profile.liveliness.name.lower(),
        "liveliness_lease_duration": _duration(profile.liveliness_lease_duration),
        "avoid_ros_namespace_conventions": bool(profile.avoid_ros_namespace_conventions),
    }


def pac_publisher_qos() -> list[dict[str, Any]]:
    """What every pac publisher offers (``pac_common.qos.PUBLISH_QOS``), for bags written offline:
    ``qos_dict`` of it, from its plain settings (no rclpy; tests/test_bags.py checks the two agree),
    the entries it leaves at rclpy's defaults written out. New dictionaries each call (YAML would
    write shared ones as aliases, which pac's bag reader refuses)."""
    from dataclasses import asdict

    from pac_common.qos_settings import PUBLISH

    never = {"sec": 0, "nsec": 0}  # rclpy's default deadline, lifespan and lease: none
    return [
        {
            **asdict(PUBLISH),
            "deadline": dict(never),
            "lifespan": dict(never),
            "liveliness": "system_default",
            "liveliness_lease_duration": dict(never),
            "avoid_ros_namespace_conventions": False,
        }
    ]


def to_yaml(value: Any) -> str:
    """Block-style YAML, keys in their order (as rosbag2 writes metadata.yaml and QoS profiles)."""
    import yaml

    return yaml.safe_dump(value, default_flow_style=False, sort_keys=False)
