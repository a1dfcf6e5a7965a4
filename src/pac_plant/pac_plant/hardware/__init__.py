"""The train's hardware around the pantograph: the actuator, the car body its base rides on, and
the sensors; each a small registry of variants by name (pure cores, explicit state, compiled
steps), all off by default. See docs/vehicle_and_hardware.md.
"""
