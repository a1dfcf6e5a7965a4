"""Experiments on the FE catenary: the benchmark lines, the experiment over lines and laws, the
live FE rig, the line's response, two pantographs."""
