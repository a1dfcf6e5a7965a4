"""The simulated pantograph-catenary plant: explicit state, one sample period per call."""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_common.parameters import ParameterError
from pac_model import model
from pac_model.pantograph_file import PantographFile
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters, positive_period

from .catenary.pantographs import plant_chain
from .hardware.actuators import Actuator, actuator_model
from .hardware.car_body import CAR_BODIES, TRACKS, RoofMotion, roof_attachment, roof_force, roof_motion
from .hardware.sensors import Sensors, sensor_noise, sensor_step, sensor_suite
from .hardware.turbulence import gusts
from .parameters import PlantOptions


@dataclass(frozen=True)
class Measurement:
    """What the rig's sensors give at one tick: y = (z1, z2) of eq. (10), and the actuator force."""

    tick: int
    time: float
    z1: float
    z2: float
    #: Force the actuator applied over the sample period that ends at this tick [N].
    actuator_force: float
    #: What the sensor suite (``sensors``) adds: head and frame accelerometers [m/s^2] and the
    #: head's load cell [N]; NaN where the suite has none (``ground``, today's: all NaN).
    head_acceleration: float = math.nan
    frame_acceleration: float = math.nan
    head_force: float = math.nan
    #: z1, z2 are measured from the roof (a train's sensors), not from the ground.
    from_roof: bool = False


@dataclass(frozen=True)
class Truth:
    """The simulator's ground truth at one tick (never available on a real rig)."""

    tick: int
    time: float
    z: tuple[float, ...]  # (z1, z2, z1dot, z2dot), eq. (4)
    stiffness: float
    contact_force: float
    in_contact: bool
    u_applied: float
    #: Contact-wire uplift from its static position at the contact point and at the nearest
    #: support [m] (FE line only; NaN for the lumped k(t) model, which has no wire).
    contact_uplift: float = math.nan
    support_uplift: float = math.nan
    #: Distance of the contact point along the line [m] (FE line only).
    contact_position: float = math.nan
    #: Height of the roof under the pantograph from its rest [m] (0: a fixed base; z is from the
    #: ground either way).
    roof_height: float = 0.0


@njit(cache=True)
def plant_rhs(
    t: float,
    z: np.ndarray,
    u: float,
    a: np.ndarray,
    theta: np.ndarray,
    omega: float,
    m1: float,
    m2: float,
    unilateral: bool,
) -> np.ndarray:
    """f(t, z) with the actuator force u held: eq. (5), k(t) of eq. (7)/(8), F of eq. (6)."""
    k = model.stiffness(t, omega, theta)
    force = model.contact_force(k, z[0], unilateral)
    return model.pantograph_rhs(z, u, force, a, m1, m2)


@njit(cache=True)
def plant_advance(z: np.ndarray, *args) -> np.ndarray:
    """z at t0 + period from z at t0, u held (ZOH): :func:`plant_advance_inplace` (its arguments
    after z) on a copy."""
    out = z.copy()
    plant_advance_inplace(out, *args)
    return out


@njit(cache=True)
def plant_rhs4(t, z0, z1, z2, z3, u, a, theta, omega, m1, m2, unilateral):
    """:func:`plant_rhs` on four numbers (eq. (5), k(t) of eq. (7)/(8), F of eq. (6))."""
    k = model.stiffness(t, omega, theta)
    force = model.contact_force(k, z0, unilateral)
    return model.pantograph_rhs4(z0, z1, z2, z3, u, force, a, m1, m2)


@njit(cache=True)
def plant_advance_inplace(
    z: np.ndarray,
    t0: float,
    period: float,
    substeps: int,
    u: float,
    a: np.ndarray,
    theta: np.ndarray,
    omega: float,
    m1: float,
    m2: float,
    unilateral: bool,
) -> None:
    """z <- z at t0 + period, u held (ZOH): ``substeps`` classical RK4 steps of :func:`plant_rhs`.

    The state is four numbers, so the stages live in registers: nothing is allocated.  The
    arithmetic is that of ``pac_common.integrate.rk4_step`` element by element (x + (h/2) k1, ...,
    x + (h/6)(k1 + 2 (k2 + k3) + k4)).
    """
    h = period / substeps
    x0, x1, x2, x3 = z[0], z[1], z[2], z[3]
    args = (u, a, theta, omega, m1, m2, unilateral)
    for i in range(substeps):
        t = t0 + i * h
        a1 = plant_rhs4(t, x0, x1, x2, x3, *args)
        c = 0.5 * h
        a2 = plant_rhs4(t + 0.5 * h, x0 + c * a1[0], x1 + c * a1[1], x2 + c * a1[2], x3 + c * a1[3], *args)
        a3 = plant_rhs4(t + 0.5 * h, x0 + c * a2[0], x1 + c * a2[1], x2 + c * a2[2], x3 + c * a2[3], *args)
        a4 = plant_rhs4(t + h, x0 + h * a3[0], x1 + h * a3[1], x2 + h * a3[2], x3 + h * a3[3], *args)
        w = h / 6.0
        x0 = x0 + w * (a1[0] + 2.0 * (a2[0] + a3[0]) + a4[0])
        x1 = x1 + w * (a1[1] + 2.0 * (a2[1] + a3[1]) + a4[1])
        x2 = x2 + w * (a1[2] + 2.0 * (a2[2] + a3[2]) + a4[2])
        x3 = x3 + w * (a1[3] + 2.0 * (a2[3] + a3[3]) + a4[3])
    z[0], z[1], z[2], z[3] = x0, x1, x2, x3


@njit(cache=True)
def quantise(x: float, q: float) -> float:
    """x rounded to the sensor resolution q (q = 0: unchanged)."""
    return q * round(x / q) if q > 0.0 else x


class Plant:
    """Eqs. (3)-(7) stepped between sample instants with the actuator force held (ZOH).

    ``advance(u)`` integrates one sample period with ``options.substeps`` RK4
    steps; the error against an adaptive high-accuracy solver is measured in
    ``tests/test_plant.py`` and documented in ``docs/numerics.md``.
    """

    def __init__(
        self,
        pantograph: PantographParameters,
        track: TrackParameters,
        catenary: CatenaryParameters,
        options: PlantOptions,
        sample_period: float,
        z0: np.ndarray | None = None,
    ) -> None:
        positive_period(sample_period)
        chain, self.own_uplift = plant_chain(pantograph, options, track.speed_kmh)
        #: The steady force that acts with u on the actuator's mass: the wind (plant_chain: the
        #: pantograph's own uplift is part of u, not added to it).
        self.uplift = options.wind_uplift
        if options.pantograph:  # eq. (5) is the paper's 2-DOF: a file of that shape, or refused
            pantograph = PantographParameters(**chain.table1("pantograph"))
        self.pantograph = pantograph
        self.track = track
        self.catenary = catenary
        self.options = options
        self.sample_period = sample_period
        self._a = model.state_matrix(pantograph)
        self._theta = catenary.theta
        self._omega = track.omega
        self._unilateral = options.contact_model == "unilateral"
        self.tick = 0
        self.z = np.zeros(4) if z0 is None else np.array(z0, dtype=float)
        self.u_applied = 0.0
        self._init_roof(chain, track.speed_kmh, 0.0)
        self._init_sensor()

    def _init_roof(self, chain: PantographFile, speed_kmh: float, behind: float) -> None:
        """The roof motion under this pantograph (``behind`` [m] behind the train's first one) and
        the roof spring and damper it reaches the actuator's mass through; None: a fixed base
        (shared with FEPlant)."""
        options = self.options
        self.roof: RoofMotion | None = None
        self._roof_k = self._roof_c = 0.0
        if options.roof_motion:
            track, car = TRACKS[options.roof_motion], CAR_BODIES[options.car_body]
            self.roof = roof_motion(track, car, speed_kmh / 3.6, options.roof_seed, behind)
            self._roof_k, self._roof_c = roof_attachment(chain)
        # The turbulent uplift: its cosines (the force as their "height") on the actuator's mass.
        self.gusts: RoofMotion | None = None
        if options.aero_turbulence > 0.0:
            if not self.own_uplift > 0.0:
                raise ParameterError(
                    "aero_turbulence",
                    options.aero_turbulence,
                    f"0 for a pantograph with no uplift of its own (mean uplift {self.own_uplift:g} N)",
                )
            self.gusts = gusts(options.aero_turbulence * self.own_uplift, options.aero_turbulence_seed)

    def _with_roof(self, force: float) -> float:
        """``force`` on the actuator's mass over this tick plus the moving roof's, through the roof
        spring and damper, and the turbulent uplift (each its mean over the tick); ``force`` itself
        for a fixed base and no turbulence."""
        roof, wind = self.roof, self.gusts
        t0, t1 = self.time, (self.tick + 1) * self.sample_period  # the next tick's time, to the bit
        if roof is not None:
            force = force + roof_force(
                roof.amplitude, roof.frequency, roof.phase, self._roof_k, self._roof_c, t0, t1
            )
        if wind is not None:  # the turbulent uplift's mean over the tick (k = 1, c = 0: the cosines')
            force = force + roof_force(wind.amplitude, wind.frequency, wind.phase, 1.0, 0.0, t0, t1)
        return force

    def roof_height(self) -> float:
        """The roof's height under the pantograph from its rest at this tick [m] (0: a fixed base)."""
        return 0.0 if self.roof is None else self.roof.at(self.time)[0]

    def _init_sensor(self) -> None:
        """Sensor noise state and the actuator (shared with FEPlant, which reuses ``measurement``
        and ``_actuate``)."""
        self._noisy = any(s > 0.0 for s in self.options.noise_std)
        self._noise_block_index = -1
        self._noise_block = np.zeros((0, 2))
        options = self.options
        suite = sensor_suite(options.sensors)
        # ``ground`` is today's sensing, done here (noise_std, quantisation): the core is not called.
        self.sensors = None if suite.name == "ground" else Sensors(suite, self.sample_period)
        self._sensed_tick = -1  # the tick whose readings ``_sensed`` holds
        self._sensed = np.full(5, math.nan)
        self.actuator = Actuator(
            actuator_model(options.actuator), options.actuator_static_force, self.sample_period
        )

    def _actuate(self, u: float) -> float:
        """The force the actuator applies over this tick for the command ``u`` (held over it): its
        mean over the tick (pac_plant.hardware.actuators); ``u`` itself for the ideal actuator."""
        if not math.isfinite(u):
            raise ValueError(f"actuator force must be finite, got {u!r}")
        return float(u) if self.actuator.ideal else self.actuator.apply(u)

    # What the compiled loop copies into its plant record (pac_rig.loop.compile_loop), read-only.
    @property
    def state_matrix(self) -> np.ndarray:
        """A of the nominal 2-DOF dynamics, eq. (5)."""
        return self._a

    @property
    def catenary_theta(self) -> np.ndarray:
        """theta of the lumped line's stiffness k(t) = v(t)^T theta, eq. (8)."""
        return self._theta

    @property
    def span_frequency(self) -> float:
        """omega of the lumped line's stiffness variation [rad/s]."""
        return self._omega

    @property
    def unilateral(self) -> bool:
        """Whether the wire can only push (contact_model unilateral)."""
        return self._unilateral

    @property
    def noisy(self) -> bool:
        """Whether the measurement adds the ground's sensor noise."""
        return self._noisy

    @property
    def roof_attachment(self) -> tuple[float, float]:
        """(k, c) of the pantograph's attachment to the roof (0, 0 on a fixed base)."""
        return self._roof_k, self._roof_c

    @property
    def time(self) -> float:
        return self.tick * self.sample_period

    @property
    def run_length(self) -> float:
        """How far [m] the pantograph can travel from where it starts: the lumped line is endless."""
        return math.inf

    def stiffness_at(self, t: float) -> float:
        return model.stiffness(t, self._omega, self._theta)

    def derivative(self, t: float, z: np.ndarray, u: float) -> np.ndarray:
        """f(t, z) with the actuator force u held: eq. (5) (or its unilateral variant)."""
        p = self.pantograph
        z = np.asarray(z, dtype=np.float64)
        f = float(u) + self.uplift  # the wind acts with u
        return plant_rhs(t, z, f, self._a, self._theta, self._omega, p.m1, p.m2, self._unilateral)

    def measurement(self) -> Measurement:
        """y_k: positions plus the seeded noise of this tick, rounded to the sensor resolution; or
        what the sensor suite reads (positions from the roof, accelerometers, load cell)."""
        if self.sensors is not None:
            r, roof = self._sense().tolist(), self.sensors.suite.datum == "roof"
            return Measurement(self.tick, self.time, r[0], r[1], self.u_applied, r[2], r[3], r[4], roof)
        z = self.z  # once: FEPlant computes it from its state
        z1, z2 = float(z[0]), float(z[1])
        if self._noisy:
            n1, n2 = self._noise(self.tick).tolist()
            z1, z2 = z1 + n1, z2 + n2
        q = self.options.quantisation
        z1, z2 = quantise(z1, q), quantise(z2, q)
        return Measurement(self.tick, self.time, z1, z2, self.u_applied)

    def _sense(self) -> np.ndarray:
        """The suite's five readings of this tick (sensors.CHANNELS), each tick's once: the low-pass
        and the latency advance one tick per tick whether or not a measurement is asked for."""
        sensors = self.sensors
        assert sensors is not None
        if self._sensed_tick != self.tick:
            truth = self.truth()
            a1, a2 = self._accelerations()
            noise = self._noise(self.tick)
            z1, z2 = truth.z[0], truth.z[1]
            sensor_step(
                sensors.params[0], sensors.state[0], z1, z2, a1, a2, truth.roof_height,
                truth.contact_force, noise, self._sensed,
            )  # fmt: skip
            self._sensed_tick = self.tick
        return self._sensed

    def _accelerations(self) -> tuple[float, float]:
        """(z1'', z2'') at this tick, from the ground, with the forces of the period that ends here
        (the left limit: the next period's command is not known yet)."""
        force = self.u_applied
        if self.roof is not None:  # the roof's spring and damper force at this instant
            height, velocity, _ = self.roof.at(self.time)
            force += self._roof_k * height + self._roof_c * velocity
        if self.gusts is not None:
            force += self.gusts.at(self.time)[0]
        d = self.derivative(self.time, self.z, force)
        return float(d[2]), float(d[3])

    _NOISE_BLOCK = 4096

    def _noise(self, tick: int) -> np.ndarray:
        """Noise of ``tick``: a pure function of (seed, tick), so a re-sent sample is the same sample.
        The ground's two (z1, z2: ``noise_std`` x standard normal), or a train suite's five
        standard normals (sensors.CHANNELS; each channel's deviation is the suite's)."""
        block = tick // self._NOISE_BLOCK
        if block != self._noise_block_index:
            seed = self.options.noise_seed
            if self.sensors is not None:
                self._noise_block = sensor_noise(seed, self._NOISE_BLOCK, block)
            else:
                rng, std = np.random.default_rng([seed, block]), np.array(self.options.noise_std)
                self._noise_block = rng.standard_normal((self._NOISE_BLOCK, 2)) * std
            self._noise_block_index = block
        return self._noise_block[tick % self._NOISE_BLOCK]

    def warm_up(self) -> None:
        """Run a tick on a copy: numba loads the compiled code now, not at the loop's first tick."""
        twin = copy.deepcopy(self)
        twin.measurement()
        twin.truth()
        twin.advance(0.0)

    def noise_rows(self, k0: int, k1: int) -> np.ndarray:
        """The noise of ticks k0..k1-1 (one row each): the numbers :meth:`measurement` adds (the
        ground's two, or a train suite's five); one row of zeros when it adds none (the compiled
        loop's ``noise``)."""
        if not (self._noisy or self.sensors is not None):
            return np.zeros((1, 2))
        out = np.empty((k1 - k0, self._noise(k0).size))
        k = k0
        while k < k1:
            self._noise(k)  # makes the block of tick k the current one
            start = k % self._NOISE_BLOCK
            end = min(k1, k - start + self._NOISE_BLOCK)
            out[k - k0 : end - k0] = self._noise_block[start : start + end - k]
            k = end
        return out

    def truth(self) -> Truth:
        t = self.time
        k = self.stiffness_at(t)
        force = model.contact_force(k, float(self.z[0]), self._unilateral)
        return Truth(
            tick=self.tick,
            time=t,
            z=tuple(float(v) for v in self.z),
            stiffness=k,
            contact_force=force,
            in_contact=force > 0.0,
            u_applied=self.u_applied,
            roof_height=self.roof_height(),
        )

    def advance(self, u: float) -> None:
        """Apply ``u`` [N] over [t_k, t_{k+1}] (through the actuator) and move to tick k + 1."""
        if self.sensors is not None:
            self._sense()  # every tick is sensed once (the suite's filters step per tick)
        applied = self._actuate(u)
        p = self.pantograph
        self.z = plant_advance(
            self.z,
            self.time,
            self.sample_period,
            self.options.substeps,
            self._with_roof(applied + self.uplift),  # the wind and the roof act with u
            self._a,
            self._theta,
            self._omega,
            p.m1,
            p.m2,
            self._unilateral,
        )
        self.tick += 1
        self.u_applied = applied
