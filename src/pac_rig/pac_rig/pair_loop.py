"""Two active pantographs on one FE line: the compiled loop with a second controlled unit.

A two-pantograph train whose pantographs both have an actuator, sensors, an observer and a law.
The line, both pantographs and the first unit's chain are one scenario's compiled loop
(:func:`pac_rig.loop.loop_tick`, the rig with ``controlled_pantograph: 0``), in which the second
pantograph is passive: it presses with the force its file holds on its actuator's mass
(``StepConstants.p_uplift``) plus ``base_force``, where the roof under it is otherwise put.
The second unit is the chain of the same scenario with ``controlled_pantograph: 1`` (its sensors,
actuator, roof, observer and law as that rig builds them: the law's design for a pantograph behind
another, the line map from where that pantograph starts): at each tick, before the first unit's
tick moves the line on, :func:`second_unit_tick` reads that pantograph's state in the shared
simulation through its own sensors, runs its observer and law, and puts the force its actuator
applies over the tick, with its roof's, into ``base_force``. One line, so each pantograph meets the
wave the other leaves in the wire.

The second unit's input is what the plant of a rig that controls it applies (``FEPlant.advance``):
the actuator's force plus the wind plus the roof's force; it has no turbulent uplift, as no passive
pantograph has (so a pair with both active is compared with a passive pair on the same terms).
Nothing of the line, the pantographs' models or the laws is written here: every step is a kernel of
the single loop (``loop.unit_chain``: the observer, the law and its safety chain, the delay and the
actuator, as ``loop_tick`` runs them; ``sensors``, ``car_body``).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_common import divergence
from pac_common.divergence import OFF_LINE
from pac_plant.catenary import step as fe_step
from pac_plant.catenary.packing import unpack
from pac_plant.fe_plant import FEPlant
from pac_plant.hardware.car_body import roof_from

from .closed_loop import BLOCK, DivergenceError
from .loop import TICK, CompiledLoop, _angles_at, _with_roof, loop_tick, measure, unit_chain

#: The second unit's pantograph in the shared simulation (``FEPlant.contact_of`` of the first
#: unit's plant: the controlled one is contact 0, the other one of a pair contact 1).
SECOND_CONTACT = 1


@njit(cache=True, error_model="numpy")
def second_unit_tick(
    k, pp, ps, fe_args, oc, os, bank, cp, cs, table, memory, noise, out
) -> tuple[int, float]:
    """Tick k of the second unit (its records: ``pp``/``ps`` the plant records of the rig that
    controls it, for its sensors, actuator and roof; ``oc``..``memory`` its observer's and law's)
    on the shared line ``fe_args`` (the first unit's), before the line moves on: its truth into
    ``out`` (a TICK record), its command, and the force on its actuator's mass over [t_k, t_k+1]
    into the simulation's ``base_force``. Returns (0, 0) or a divergence (code, value), as
    ``loop_tick``."""
    cf, ci, cl, sf, si, sl, flexibility, readings = fe_args
    c, st = unpack(cf, ci, cl, sf, si, sl)
    head, frame = c.p_heads[SECOND_CONTACT], c.p_inputs[SECOND_CONTACT]
    # Its truth, as the rig that controls it reads it (fe_kernels.fe_output, a fixed datum).
    z = ps.z
    z[0], z[1], z[2], z[3] = st.p[head] - pp.datum, st.p[frame] - pp.datum, st.vp[head], st.vp[frame]
    force, position = fe_step.pantograph_contact(c, st, SECOND_CONTACT)
    out.roof_height = 0.0
    if pp.roof:
        _angles_at(k, pp, ps)
        roof_from(pp.roof_amplitude, pp.roof_frequency, ps.roof_cos, ps.roof_sin, ps.roof)
        out.roof_height = ps.roof[0]
    y1, y2 = measure(pp, ps, z, st.ap[head], st.ap[frame], force, noise, out)  # its own sensors
    out.tick, out.time = k, k * pp.dt
    out.y[0], out.y[1] = y1, y2
    out.actuator_force = ps.u_applied
    out.z[:] = z
    out.contact_force, out.in_contact, out.u_applied = force, force > 0.0, ps.u_applied
    out.contact_position = position
    out.stiffness, out.contact_uplift, out.support_uplift = np.nan, np.nan, np.nan
    out.pantograph_contact_force[:] = np.nan
    out.pantograph_contact_position[:] = np.nan
    out.pantograph_contact_uplift[:] = np.nan
    out.pantograph_support_uplift[:] = np.nan
    code, value, applied = unit_chain(k, pp, ps, oc, os, bank, cp, cs, table, memory, y1, y2, out)
    if code:
        return code, value
    # What a rig controlling it applies (loop._plant_advance: the wind with u, the roof's force),
    # less what the line already holds on that pantograph's actuator mass (its file's uplift).
    total = _with_roof(k, pp, ps, applied + pp.uplift)
    st.base_force[SECOND_CONTACT] = total - c.p_uplift[SECOND_CONTACT]
    ps.u_applied = applied
    return 0, 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def run_pair_block(
    k0, k1, pp, ps, fe_args, oc, os, bank, cp, cs, table, memory, noise, out,
    pp2, ps2, oc2, os2, bank2, cp2, cs2, table2, memory2, noise2, out2,
) -> tuple[int, int, float]:  # fmt: skip
    """Ticks k0..k1-1 of both units (the first's records, then the second's; 1-element arrays as
    ``loop.run_block`` takes them) into ``out`` / ``out2``; (ticks reached, code, value): a code of
    the second unit is offset by ``SECOND_UNIT``."""
    for k in range(k0, k1):
        i = min(k - k0, noise.shape[0] - 1)
        j = min(k - k0, noise2.shape[0] - 1)
        code, value = second_unit_tick(
            k, pp2[0], ps2[0], fe_args, oc2[0], os2[0], bank2, cp2[0], cs2[0], table2, memory2,
            noise2[j], out2[k - k0],
        )  # fmt: skip
        if code:
            return k, SECOND_UNIT + code, value
        code, value = loop_tick(
            k, pp[0], ps[0], fe_args, oc[0], os[0], bank, cp[0], cs[0], table, memory, noise[i], out[k - k0]
        )
        if code:
            return k, code, value
    return k1, 0, 0.0


#: Added to a divergence code of the second unit (:func:`run_pair_block`).
SECOND_UNIT = 1000


@dataclass
class PairLoop:
    """Both units' records: the first's loop (it holds the line) and the second's (its plant
    records are the sensors, actuator and roof of a rig that controls it)."""

    first: CompiledLoop
    second: CompiledLoop

    def run(
        self, k0: int, k1: int, noise: np.ndarray, noise2: np.ndarray, out: np.ndarray, out2: np.ndarray
    ) -> tuple[int, int, float]:
        """Ticks k0..k1-1 into ``out`` (the first unit, with every pantograph's contact) and
        ``out2`` (the second unit); (ticks reached, divergence code, value)."""
        a, b = self.first, self.second
        return run_pair_block(
            k0, k1, *a.args(), noise, out,
            b.plant_params, b.plant_state, b.observer_consts, b.observer_state, b.bank,
            b.controller_params, b.controller_state, b.table, b.memory, noise2, out2,
        )  # fmt: skip


def pair_loop(
    first_plant: FEPlant, first: CompiledLoop, second_plant: FEPlant, second: CompiledLoop
) -> PairLoop:
    """The pair of ``first`` (the rig controlling pantograph 0 of a pair on an FE line) and
    ``second`` (the same line and train, the rig controlling pantograph 1); ValueError where they
    are not one train: not two pantographs, not the same line's start, or a law without kernel.
    The second's plant records lose their turbulent uplift (a passive pantograph has none) and
    the first's its passive roof (the second unit puts that roof's force in itself)."""
    a, b = first_plant.options, second_plant.options
    if a.pantographs != b.pantographs or not (a.all_pantographs_active and b.all_pantographs_active):
        raise ValueError("a pair loop is two rigs of one train with all_pantographs_active")
    if (a.controlled_pantograph, b.controlled_pantograph) != (0, 1):
        raise ValueError("the first rig controls the leading pantograph, the second the trailing one")
    if first_plant.sim.x != second_plant.sim.x or first.block is not None or second.block is not None:
        raise ValueError("a pair loop runs pac's kernel laws on one line from one start")
    p, q = first.plant_params[0], second.plant_params[0]
    if p["static_wire"] or q["static_wire"]:
        raise ValueError("a pair loop measures from a fixed datum (fe_datum: fixed)")
    p["passive_roofs"] = 0
    q["gusts"] = False
    return PairLoop(first, second)


def run_pair_blocks(
    ticks: int, first_plant: FEPlant, second_plant: FEPlant, loop: PairLoop
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The ticks of both units as TICK blocks of up to BLOCK ticks (the first unit's, the second's);
    DivergenceError on divergence (the second unit's named so), ValueError past the line's end."""
    for k0 in range(0, ticks, BLOCK):
        k1 = min(ticks, k0 + BLOCK)
        out, out2 = np.empty(k1 - k0, TICK), np.empty(k1 - k0, TICK)
        noise, noise2 = first_plant.noise_rows(k0, k1), second_plant.noise_rows(k0, k1)
        reached, code, value = loop.run(k0, k1, noise, noise2, out, out2)
        yield out[: reached - k0], out2[: reached - k0]
        if code == OFF_LINE:
            raise ValueError(divergence.reason(code, value))
        if code >= SECOND_UNIT:
            raise DivergenceError(reached, "second unit: " + divergence.reason(code - SECOND_UNIT, value))
        if code:
            raise DivergenceError(reached, divergence.reason(code, value))
