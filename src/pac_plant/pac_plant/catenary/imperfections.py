"""Real-line imperfections applied to a ``CatenaryData``: each off by default, seeded.

* Contact-wire height errors at the droppers: each dropper's design pre-sag plus an independent
  normal error (standard deviation ``height_error`` [m]); the dropper lengths are then solved
  for the erroneous heights, as an installer who cut them to a wrong measure would leave them.
  The errors are drawn for a period of at least ``IMPERFECT_SPANS`` spans (the line's period
  repeated), so on the plant's endless line they repeat every such period.
* A worn contact wire: a fraction ``wear`` of its section lost, uniformly along the line: mass
  per length x (1 - wear), bending stiffness x (1 - wear)^2 (a section's second moment scales
  with its area squared at a fixed shape); the tension stays (the line's tensioning keeps it).

No standard tolerance is built in: the height error and the wear are the user's numbers
(docs/catenary.md, "Imperfections").
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .data import CatenaryData

#: Spans over which the height errors are drawn (at least; a whole number of the line's periods).
IMPERFECT_SPANS = 10


def apply_imperfections(data: CatenaryData, height_error: float, wear: float, seed: int) -> CatenaryData:
    """``data`` with the imperfections; ``data`` itself when both are 0."""
    if not (math.isfinite(height_error) and height_error >= 0.0):
        raise ValueError(f"height_error = {height_error!r}: allowed a finite number >= 0 m")
    if not (math.isfinite(wear) and 0.0 <= wear < 1.0):
        raise ValueError(f"wear = {wear!r}: allowed a number in [0, 1)")
    out = data
    if wear > 0.0:
        c = data.contact
        out = dataclasses.replace(
            out, contact=dataclasses.replace(c, rho=c.rho * (1.0 - wear), ei=c.ei * (1.0 - wear) ** 2)
        )
    if height_error > 0.0:
        rng = np.random.default_rng(seed)
        p = len(data.spans)
        repeats = math.ceil(IMPERFECT_SPANS / p)
        spans = []
        for k in range(repeats * p):
            span = data.spans[k % p]
            errors = rng.normal(0.0, height_error, len(span.presag))
            presag = tuple(float(s + e) for s, e in zip(span.presag, errors, strict=True))
            stitch = span.stitch
            if stitch is not None:
                st_errors = rng.normal(0.0, height_error, len(stitch.presag))
                stitch = dataclasses.replace(
                    stitch, presag=tuple(float(s + e) for s, e in zip(stitch.presag, st_errors, strict=True))
                )
            spans.append(dataclasses.replace(span, presag=presag, stitch=stitch))
        out = dataclasses.replace(out, spans=tuple(spans))
    return out
