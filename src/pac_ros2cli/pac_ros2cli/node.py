"""``ros2 node list | info``."""

from __future__ import annotations

from .common import join_name, parser
from .graph import SPIN_TIME, Graph


def node_list(args: list[str]) -> int:
    p = parser("node list")
    p.add_argument("-a", "--all", action="store_true", help="also hidden nodes (names starting with _)")
    p.add_argument("-c", "--count-nodes", action="store_true")
    p.add_argument("--spin-time", type=float, default=SPIN_TIME, help="max wait for discovery [s]")
    a = p.parse_args(args)
    with Graph() as graph:
        names = graph.settled(lambda: graph.node_names(hidden=a.all), a.spin_time)
    if a.count_nodes:
        print(len(names))
    elif names:
        print("\n".join(names))
    return 0


def node_info(args: list[str]) -> int:
    p = parser("node info")
    p.add_argument("node_name")
    a = p.parse_args(args)
    with Graph() as graph:
        name, ns = graph.find_node(a.node_name)
        n = graph.node
        sections = graph.settled(
            lambda: [
                ("Subscribers", n.get_subscriber_names_and_types_by_node(name, ns)),
                ("Publishers", n.get_publisher_names_and_types_by_node(name, ns)),
                ("Service Servers", n.get_service_names_and_types_by_node(name, ns)),
                ("Service Clients", n.get_client_names_and_types_by_node(name, ns)),
                ("Action Servers", []),
                ("Action Clients", []),
            ]
        )
    print(join_name(ns, name))
    for title, items in sections:
        print(f"  {title}:")
        for topic, types in sorted(items):
            print(f"    {topic}: {', '.join(types)}")
    return 0
