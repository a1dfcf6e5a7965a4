"""Benchmarks that print tables: the loop, the live rig, the batch, node start-up, the FE step,
campaigns; the soak run."""
