"""The paper's 2-DOF pantograph on the finite-element catenary, with the interface of ``Plant``.

``catenary_model:=fe``: the pantograph of Table 1 (eqs. 3-4 with the actuator force u on
the lower mass m2) runs on the FE simple catenary of ``pac_plant.catenary`` at the track
speed instead of on the spring k(t) of eq. (7). The observer and controller are unchanged.
``pantograph:=NAME|PATH`` replaces that pantograph by any chain of a pantograph file
(docs/catenary.md, "The pantograph file"), its degrees of freedom ordered head, actuator's mass,
the rest (z1, z2 below are those two); its uplift and the wind act with u on the actuator's mass.

Coordinates: z1, z2 are the head and frame heights measured from the static contact-wire
height at the start point (a support, where the pre-sag is 0), i.e. from a fixed datum,
as a real rig would measure them (``fe_datum:=static_wire`` measures them from the
static, pre-sagged wire under the contact point instead); at tick 0 the head just touches the wire (F = 0) and
everything is at rest, as in the lumped plant. The line is endless (a moving window of
``WINDOW_SPANS`` spans, see ``ContactSimulation``), so a live run can go on until stopped; a whole
line (a catenary file with a layout rule, ``CatenaryData.whole_line``) is built from end to end
and run once from its first interior support (docs/catenary.md, "A whole line").
Truth: ``stiffness`` is the line's static point stiffness at the contact point (droppers
taut), ``contact_force`` the penalty force, plus the wire uplift at the contact point
and at the nearest support.

``pantographs:=[0.0, 200.0]``: more pantographs on the same line, each this far behind the first;
``controlled_pantograph`` is the one above (u, measurement, truth), the others are passive
(``passive_pantograph``, ``passive_pantograph_uplift``); ``pantograph_truths()`` gives every
one's contact, and the window grows by the spacing (``window_periods``; docs/catenary.md,
"Several pantographs").
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from pac_common.parameters import ParameterError
from pac_model.pantograph_file import load_pantograph_file
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters, positive_period

from .catenary.catenary_file import load_catenary
from .catenary.data import CatenaryData, NumericalOptions
from .catenary.imperfections import apply_imperfections
from .catenary.integrator import ContactSimulation, PassivePantograph, rear_periods
from .catenary.line import Line
from .catenary.pantographs import LumpedPantograph, head_first, lumped, plant_chain
from .catenary.sections import SectionedLine
from .catenary.step import (
    CONTACT_UPLIFT,
    STATIC_HEIGHT,
    STATIC_SLOPE,
    STATIC_STIFFNESS,
    SUPPORT_UPLIFT,
    pantograph_contact,
)
from .hardware.car_body import CAR_BODIES, TRACKS, RoofMotion, roof_attachment, roof_force, roof_motion
from .parameters import PlantOptions
from .plant import Plant, Truth

#: Spans in the moving window; the contact point stays in spans 4..6 of it (4 behind, >= 4 ahead).
WINDOW_SPANS = 10
START_SPAN = 4


def window_periods(data: CatenaryData, spacing: float = 0.0) -> tuple[int, int]:
    """(periods in the endless window, the period the first pantograph starts at): the window shifts
    by whole periods of the line, so it holds at least WINDOW_SPANS spans and 3 periods (one behind
    the contact point, one it runs in, one ahead); one span per period gives 10 and 4. Pantographs
    up to ``spacing`` [m] behind the first add ceil(spacing / period) periods at the rear (and the
    start moves as far forward): the last one then runs as far from the rear end as the first."""
    p, rear = len(data.spans), rear_periods(data.period, spacing)
    return max(3, math.ceil(WINDOW_SPANS / p)) + rear, max(1, START_SPAN // p) + rear


def passive_pantograph(options: PlantOptions, speed_kmh: float) -> tuple[LumpedPantograph, float]:
    """A passive pantograph (``passive_pantograph``, a pantograph file) and the constant force on its
    actuator's mass: ``passive_pantograph_uplift``, or (0) the file's uplift at ``speed_kmh``, plus
    the wind."""
    chain = load_pantograph_file(options.passive_pantograph, "passive_pantograph")
    uplift = options.passive_pantograph_uplift or chain.uplift(speed_kmh)
    return lumped(chain), uplift + options.wind_uplift


@functools.lru_cache(maxsize=4)
def line_and_flexibility(
    data: CatenaryData, numerics: NumericalOptions, n_spans: int
) -> tuple[Line, np.ndarray]:
    """The line (matrices, static state, dropper lengths) and its element flexibilities: a pure
    function of the data, built once per process and shared by every plant on it (nothing writes
    to them after this); they are most of an FE plant's set-up (~0.7 s of CPU), which a campaign
    would otherwise pay per run."""
    line = SectionedLine(data, numerics) if data.sections else Line(data, numerics, n_spans=n_spans)
    return line, line.element_flexibility()


#: Points per period of the line at which equivalent_contact_stiffness samples the static stiffness
#: (every 0.25 m on a 55 m span: finer than the 0.5 m elements, so each element counts).
STIFFNESS_POINTS = 220


@functools.lru_cache(maxsize=8)
def equivalent_contact_stiffness(catenary: str, element_size: float) -> float:
    """The FE line's equivalent contact stiffness for a linear design (pid, lqr): the mean over one
    period of its design spans of the static point stiffness at the contact point (``Line.static_stiffness``,
    droppers taut), sampled at STIFFNESS_POINTS midpoints, on the mesh the plant uses. The mean is what
    the lumped model's k0 is (eq. (7): k(t) = k0 (1 + alpha cos(omega t - beta)) averages to k0). The
    design line, the file's stated period, not a line drawn from it (layout, deviation) nor the
    imperfections: what the infrastructure manager publishes, which a train may know."""
    line_file = load_catenary(catenary)
    data = line_file.drawing.base if line_file.drawing is not None else line_file.data
    numerics = dataclasses.replace(line_file.numerics, element_size=element_size)
    periods, start = window_periods(data)
    # The same line (and cache entry) as a plant on the design line, so that plant's set-up is paid once.
    line, _ = line_and_flexibility(data, numerics, periods * len(data.spans))
    xs = (start + (np.arange(STIFFNESS_POINTS) + 0.5) / STIFFNESS_POINTS) * data.period
    return float(np.mean(line.static_stiffness(xs)))


@dataclasses.dataclass(frozen=True)
class PantographTruth:
    """One pantograph's contact at a tick: force [N], position along the line [m], the wire's uplift
    there and at the nearest support [m], and whether it is the rig's controlled one."""

    contact_force: float
    contact_position: float
    contact_uplift: float
    support_uplift: float
    controlled: bool


@dataclasses.dataclass(frozen=True)
class PassiveRoof:
    """The moving roof under a passive pantograph: its contact in the simulation, the roof's motion
    there, and the roof spring and damper [N/m, N s/m] it reaches the pantograph's actuator mass by."""

    contact: int
    motion: RoofMotion
    stiffness: float
    damping: float


class FEPlant(Plant):
    """Same interface as ``Plant``: tick, time, measurement(), truth(), advance(u), sample_period."""

    def __init__(
        self,
        pantograph: PantographParameters,
        track: TrackParameters,
        catenary: CatenaryParameters | None,
        options: PlantOptions,
        sample_period: float,
        data: CatenaryData | None = None,
    ) -> None:
        positive_period(sample_period)
        self.pantograph = pantograph
        self.track = track
        self.options = options
        self.sample_period = sample_period
        if data is None:
            line_file = load_catenary(options.catenary)
            data = line_file.line(options.drawn_line_seed)
            numerics = line_file.numerics
        else:
            numerics = NumericalOptions()
        numerics = dataclasses.replace(numerics, element_size=options.fe_element_size)
        data = apply_imperfections(
            data, options.fe_height_error, options.fe_wear, options.fe_imperfection_seed
        )
        self.data = data
        if options.fe_window_spans > 0.0 and not data.whole_line:
            raise ParameterError(
                "fe_window_spans",
                options.fe_window_spans,
                f"0 on {data.name or 'this line'}: an endless line is a window already (a moving "
                "window is for a whole line, drawn by a layout rule)",
            )
        if 0.0 < options.fe_window_spans < 2.0:
            raise ParameterError(
                "fe_window_spans", options.fe_window_spans, "0 (the whole line) or 2 spans and more"
            )
        spacings = options.pantographs
        # A whole line (drawn by a layout rule) runs once from end to end; a period, endlessly.
        periods, start = (1, 1) if data.whole_line else window_periods(data, spacings[-1])
        self.line, self._flex = line_and_flexibility(self.data, numerics, periods * len(data.spans))
        if data.whole_line:  # the first interior support with every pantograph on the line
            start = max(1, int(np.searchsorted(self.line.layout.support_x, spacings[-1])))
        start_x = float(self.line.layout.support_x[start]) if data.whole_line else start * data.period
        chain, self.own_uplift = plant_chain(pantograph, options, track.speed_kmh)
        self.uplift = options.wind_uplift  # acts with u (the own uplift is part of u: plant_chain)
        ctrl = options.controlled_pantograph
        model, force = passive_pantograph(options, track.speed_kmh)
        passive = tuple(PassivePantograph(model, lag, force) for k, lag in enumerate(spacings) if k != ctrl)
        #: contact of each pantograph of ``pantographs`` in the simulation (the controlled one is 0)
        self.contact_of = [0 if k == ctrl else 1 + k - (k > ctrl) for k in range(len(spacings))]
        self.sim = ContactSimulation(
            self.line,
            head_first(lumped(chain)),  # z1 = the head, z2 = the actuator's mass
            sample_period / options.fe_substeps,
            track.speed_kmh / 3.6,
            start_x,
            endless=not data.whole_line,
            lag=spacings[ctrl],
            passive=passive,
            window_spans=options.fe_window_spans,
        )
        if np.any(self.sim.uplifts[1:]) or (self.own_uplift and np.any(self.sim.panto.ground_stiffness)):
            # A pantograph's static uplift is its force on the wire at its working height: its roof
            # springs are relaxed in the static state under its own uplift (not at the touching
            # start, where they would take k_roof times the wire's static rise off the force).
            self.sim.relax_roof_springs(self.own_uplift)
        # Every contact column of the stretch the contact point sweeps in the window (~10 ms):
        # no tick pays one later.
        # On a whole line, the first two spans' (the step solves the others' at first use).
        ahead = float(self.line.layout.support_x[start + 2]) if data.whole_line else self.sim.shift_at
        self.sim.prepare_contact_columns(start_x, ahead)
        self.datum = self.line.static_height(self.sim.x - self.sim.lags[0])
        self._readings = np.zeros(5)  # contact_readings at the present contact point
        self.sim.readings(self._flex, self._readings)
        self.tick = 0
        self.u_applied = 0.0
        self._init_roof(chain, track.speed_kmh, spacings[ctrl])
        self.passive_roofs = self._passive_roofs(options, spacings, track.speed_kmh)
        self._init_sensor()

    def _passive_roofs(
        self, options: PlantOptions, spacings: tuple[float, ...], speed_kmh: float
    ) -> tuple[PassiveRoof, ...]:
        """The roof under each passive pantograph where the roof moves: the same drawn track as the
        controlled one's, under a car as far behind the first as the pantograph is (every car of
        the train runs over the same track), through the passive pantograph file's own roof spring
        and damper; () on a fixed roof."""
        if self.roof is None:
            return ()
        track, car = TRACKS[options.roof_motion], CAR_BODIES[options.car_body]
        k, c = roof_attachment(load_pantograph_file(options.passive_pantograph, "passive_pantograph"))
        speed, seed = speed_kmh / 3.6, options.roof_seed
        return tuple(
            PassiveRoof(self.contact_of[j], roof_motion(track, car, speed, seed, behind), k, c)
            for j, behind in enumerate(spacings)
            if j != options.controlled_pantograph
        )

    @property
    def z(self) -> np.ndarray:
        """(z1, z2, z1', z2') of eq. (4) from the FE state (heights above the datum, ``fe_datum``)."""
        return np.array(self._heights())

    @z.setter
    def z(self, value: np.ndarray) -> None:
        # Plant.z is a plain attribute; here it follows from the FE state and cannot be set.
        raise AttributeError("FEPlant.z follows from the FE state: it cannot be set")

    def _heights(self) -> tuple[float, float, float, float]:
        """``z`` as Python floats (a tick reads it twice: plain lists are the cheap way out)."""
        p, vp = self.sim.state.p.tolist(), self.sim.state.vp.tolist()
        if self.options.fe_datum == "static_wire":
            # The datum moves with the contact point along the pre-sagged static wire.
            r = self._readings
            datum, rate = float(r[STATIC_HEIGHT]), self.sim.speed * float(r[STATIC_SLOPE])
        else:
            datum, rate = float(self.datum), 0.0
        return (p[0] - datum, p[1] - datum, vp[0] - rate, vp[1] - rate)

    @property
    def flexibility(self) -> np.ndarray:
        """The line's flexibility at the contact points (contact_readings reads it)."""
        return self._flex

    @property
    def readings(self) -> np.ndarray:
        """contact_readings at the present contact point (a copy)."""
        return self._readings.copy()

    @property
    def run_length(self) -> float:
        """How far [m] the pantograph can travel from where it starts: the rest of a whole line (it
        ends there), any distance on the endless window of a periodic one."""
        return self.line.length - self.sim.x if self.data.whole_line else math.inf

    def stiffness_at(self, t: float | None = None) -> float:
        """Static point stiffness of the line at the current contact point [N/m] (``t`` ignored)."""
        return float(self._readings[STATIC_STIFFNESS])

    def truth(self) -> Truth:
        s, r = self.sim, self._readings.tolist()
        force = s.contact_force
        return Truth(
            tick=self.tick,
            time=self.time,
            z=self._heights(),
            stiffness=r[STATIC_STIFFNESS],
            contact_force=force,
            in_contact=force > 0.0,
            u_applied=self.u_applied,
            contact_uplift=r[CONTACT_UPLIFT],
            support_uplift=r[SUPPORT_UPLIFT],  # at the support nearest x
            contact_position=s.position - s.lags[0],
            roof_height=self.roof_height(),
        )

    def pantograph_truths(self) -> list[PantographTruth]:
        """What each pantograph of ``pantographs`` (in that order) feels at this tick."""
        s, out, r = self.sim, [], np.zeros(5)
        for k in self.contact_of:
            force, position = pantograph_contact(s.constants, s.state, k)
            s.readings_at(self._flex, s.x - s.lags[k], r)
            out.append(
                PantographTruth(
                    contact_force=float(force),
                    contact_position=float(position),
                    contact_uplift=float(r[CONTACT_UPLIFT]),
                    support_uplift=float(r[SUPPORT_UPLIFT]),
                    controlled=k == 0,
                )
            )
        return out

    def _accelerations(self) -> tuple[float, float]:
        """(z1'', z2'') at this tick: the Newmark state's (the end of the period that ends here)."""
        ap = self.sim.state.ap
        return float(ap[0]), float(ap[1])

    def advance(self, u: float) -> None:
        """Apply ``u`` [N] over [t_k, t_{k+1}] (held, through the actuator) and move to tick k + 1."""
        if self.sensors is not None:
            self._sense()  # every tick is sensed once (the suite's filters step per tick)
        applied = self._actuate(u)
        if self.passive_roofs:  # each passive pantograph's roof force, its mean over the tick
            t0, t1, base = self.time, (self.tick + 1) * self.sample_period, self.sim.state.base_force
            for roof in self.passive_roofs:
                m = roof.motion
                base[roof.contact] = roof_force(
                    m.amplitude, m.frequency, m.phase, roof.stiffness, roof.damping, t0, t1
                )
        # The wind acts with u on the actuator's mass (the pantograph's own uplift is part of u).
        self.sim.advance(
            self._with_roof(applied + self.uplift), self.options.fe_substeps, self._flex, self._readings
        )
        self.tick += 1
        self.u_applied = applied


def several_pantographs(plant: Plant) -> FEPlant | None:
    """``plant`` when it reports every pantograph on ``pantograph_truth`` (``pantograph_truths()``):
    an FE line with several; None otherwise (one pantograph: PlantTruth is all there is to say).
    The plant node publishes that topic, and the offline simulator records it, exactly then."""
    return plant if isinstance(plant, FEPlant) and len(plant.options.pantographs) > 1 else None
