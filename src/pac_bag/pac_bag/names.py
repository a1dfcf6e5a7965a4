"""Topic names in bags: the one place where recorded names are normalised."""

from __future__ import annotations


def topic_key(name: str) -> str:
    """The name pac uses for a recorded topic: ``/measurement`` (ros2 bag) and ``measurement``
    (bags before the fully qualified names) are both ``measurement``."""
    return name.lstrip("/")


def qualified(topic: str) -> str:
    """The fully qualified name a topic is recorded under, as ``ros2 bag record`` does."""
    return "/" + topic.lstrip("/")
