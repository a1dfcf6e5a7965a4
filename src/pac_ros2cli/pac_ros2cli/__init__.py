"""A stand-in for ros2cli (which has no PyPI wheels): the daily `ros2` verbs, one function each.

:mod:`pac_ros2cli.main` dispatches ``ros2 <verb> <sub> ...`` through :data:`~pac_ros2cli.main.COMMANDS`;
each verb lives in the module named after it.
"""
