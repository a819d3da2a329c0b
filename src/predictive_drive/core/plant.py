"""The drive plant: inverter + machine + mechanics, advanced one control period per command.

Each period is split into the command's piecewise-constant switching segments
(docs/physics.md#the-inverter-and-the-command) and each segment is integrated with the integrator
passed in, in sub-steps of at most ``max_substep`` (the IM's exact discretisation for frozen ω, the
PMSM's fused RK4).

A real drive (docs/physics.md#a-real-drive), each part off by default: the command may act
``actuation_delay_steps`` periods after its sample (the periods before the first command acts
hold every phase low); dead time and device drops split the period further, at every switching
edge, into segments whose leg voltages follow the phase currents' signs; and ``sensors`` turn the
true currents and position into what the controller measures (the truth published beside).

With ``losses`` (:mod:`.losses`) the plant books each device's losses, the machine's, and the
temperatures they lead to; the devices' on-state voltages are then the drops of its equations
(one model of a conducting device), and its R_s, R_r, ψ_f follow the machine's temperatures.

With ``period_means`` the state also carries what happened between the samples: the means of the
torque, the flux magnitude and the current over the period that ended at k, of their squares and
of the current in the rotor's frame (:data:`PERIOD_MEANS`; NaN without it). They are integrated
over every sub-step of every segment (:meth:`InverterPlant._piece`), so the ripple a carrier
hides from samples taken at its period's
boundaries is counted (docs/physics.md#continuous-time-figures). They change nothing of the
trajectory: the sub-steps are the ones the integrator takes anyway, bit for bit.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .devices import Device
from .inverter import clarke, inverse_clarke, segments
from .losses import Ledger, LossParams
from .machines import Machine
from .machines.induction import IM_STATE, InductionCoefficients, InductionMotor, induction_exact
from .machines.pmsm import PMSM, PMSM_STATE, PMSMCoefficients, pmsm_rk4
from .sensors import Sensors
from .signals import COMMAND_INDEX, PULSES, Losses, PhasePulses, State, new_record
from .thermal import COPPER_ALPHA, resistance_at
from .timebase import StepProfile

__all__ = [
    "PERIOD_MEANS",
    "PLANTS",
    "InductionPlant",
    "InverterPlant",
    "PMSMPlant",
    "make_plant",
    "rk4",
]

Dynamics = Callable[[float, Any, Any, Any], Any]
TWO_PI = 2.0 * math.pi
#: what the inverter does before the first command acts (actuation delay): every phase low
ALL_LOW = PhasePulses(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
_K = COMMAND_INDEX.k
_IM_I, _IM_PSI, _IM_W, _IM_TH = IM_STATE.i_s, IM_STATE.psi_s, IM_STATE.omega_m, IM_STATE.theta_m
_PM_I, _PM_W, _PM_TH = PMSM_STATE.i_dq, PMSM_STATE.omega_m, PMSM_STATE.theta_m
#: a device's place in its leg (:data:`~.signals.DEVICES`): upper transistor and diode, lower
_T_HI, _D_HI, _T_LO, _D_LO = range(4)
#: the state's fields that are means over the period that ended at k, in the order
#: :meth:`InverterPlant._means` gives them
PERIOD_MEANS = (
    "torque_avg",
    "torque_sq_avg",
    "flux_avg",
    "flux_sq_avg",
    "i_alpha_avg",
    "i_beta_avg",
    "current_sq_avg",
    "i_d_avg",
    "i_q_avg",
)
#: (T_e, |ψ_s|, i_s in the rotor frame, θ_e unwrapped, e^{jθ_e}) at one instant
Point = tuple[float, float, complex, float, complex]


def rk4(f: Dynamics) -> Callable[..., tuple[Any, ...]]:
    """Classic 4th-order Runge-Kutta of ``f(t, x, u, c)``: returns ``integrate(t, x, u, c, h, n)``."""

    def integrate(
        t: float, x: tuple[Any, ...], u: Any, c: Any, h: float, n: int
    ) -> tuple[Any, ...]:
        return _rk4(f, t, x, u, c, h, n)

    return integrate


def _rk4(
    f: Dynamics, t: float, x: tuple[Any, ...], u: Any, c: Any, h: float, n: int
) -> tuple[Any, ...]:
    dt = h / n
    half = 0.5 * dt
    sixth = dt / 6.0
    for _ in range(n):
        k1 = f(t, x, u, c)
        k2 = f(t + half, tuple(a + half * b for a, b in zip(x, k1)), u, c)
        k3 = f(t + half, tuple(a + half * b for a, b in zip(x, k2)), u, c)
        k4 = f(t + dt, tuple(a + dt * b for a, b in zip(x, k3)), u, c)
        x = tuple(
            a + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
            for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4)
        )
        t += dt
    return x


class InverterPlant:
    """A machine on a two-level inverter with a stepped load
    (docs/physics.md#the-inverter-and-the-command; docs/physics.md#mechanics-and-load).

    ``step(command)`` applies command k for one period Ts and returns state k+1: each switching segment
    is integrated with ``integrator`` (default: the machine's own, see above) in sub-steps of at most
    ``max_substep``. Subclasses name the machine's coefficients, initial state and integrator, and
    say what the state publishes. Initial switches: 000.
    """

    coefficients: Any  #: class with ``of(motor)``: the machine's precomputed constants
    #: the motor's parameters as its coefficients read them, taken once (see ``_heat``)
    _cold: dict[str, Any] | None = None
    x0: tuple[Any, ...]  #: initial state
    speed_index: int  #: where ω_m is in the state
    angle_index: int  #: where θ_m is in the state
    default_integrator: Callable[..., tuple[Any, ...]]

    def __init__(
        self,
        motor: Any,
        *,
        ts: float,
        u_dc: float,
        load: StepProfile,
        max_substep: float,
        integrator: Callable[..., tuple[Any, ...]] | None = None,
        actuation_delay_steps: int = 0,
        dead_time: float = 0.0,
        device_drop: float = 0.0,
        sensors: Sensors | None = None,
        period_means: bool = False,
        held_speed: StepProfile | None = None,
        u_dc_gain: float = 1.0,
        losses: LossParams | None = None,
        device: Device | None = None,
    ) -> None:
        self.motor = motor
        self.ts = ts
        self.u_dc = u_dc
        self._u_dc_seen = u_dc * u_dc_gain  #: the DC link as measured (a sensor's gain error)
        x0 = self.x0
        #: the speed a load machine holds (rad/s), by step; None: a free shaft
        self._held = None if held_speed is None else held_speed.sampled(ts)
        self._coef = self._coefficients(motor)
        if self._held is not None:
            x0 = self._with_speed(x0, self._held.at(0))
        self._load = load.sampled(ts)
        self._max_substep = max_substep
        self._integrate = integrator or type(self).default_integrator
        self._volts = {s: u_dc * clarke(*s) for s in _ALL_STATES}
        self.k = 0
        self.load = self._load.at(0)  #: N·m, load torque during the coming period k
        self.x: tuple[Any, ...] = x0
        self.switches = (0, 0, 0)
        self._transitions = 0
        #: the commands issued but not yet acting, oldest first (actuation delay)
        self._pending: deque[Sequence[float]] | None = (
            deque([ALL_LOW] * actuation_delay_steps) if actuation_delay_steps else None
        )
        self._dead = dead_time / ts  #: dead time as a share of Ts
        #: the losses booked (None: none); with them every period takes the real inverter's path
        self._ledger: Ledger | None = None
        self._ledger_params = losses or LossParams()
        if losses is not None and losses.on:
            self._ledger = Ledger(
                losses, device, ts=ts, u_dc=u_dc, drop=device_drop, heat=self._heat,
                rotor=self._rotor(), torque=None if self._held is None else self._torque,
            )  # fmt: skip
        #: each device's on-state voltage v0 + r·|i| (V, Ω; per :data:`~.signals.DEVICES`), and
        #: whether a transistor conducts reverse current while on (a MOSFET's channel)
        on = self._ledger
        if on is not None and on.batched:
            on.tail = self._tail
        self._v0 = on.v0 if on is not None else [device_drop] * 12
        self._r = on.r if on is not None else [0.0] * 12
        self._reverse = on is not None and on.reverse
        self._real_inverter = dead_time > 0.0 or device_drop > 0.0 or on is not None
        rotor = self._rotor()
        #: what the ledger's kernel takes of a segment's state besides its currents: where the
        #: state holds an induction motor's stator flux, whether the torque is wanted (a load
        #: machine holds the speed); and whether the stator flux at a period's end is (iron)
        self._seg_extras = (rotor[0] if rotor is not None else None, self._held is not None)
        self._psi_wanted = on is not None and on.wants_flux
        self._carry = [0.0, 0.0, 0.0]  #: dead time of each leg running on into this period
        self.sensors = sensors
        #: the period means the state publishes (:data:`PERIOD_MEANS`): NaN unless
        #: ``period_means``; at k = 0, the values at 0 (the limit of an empty period)
        self._avg: tuple[float, ...] = (math.nan,) * len(PERIOD_MEANS)
        self._sums = [0.0, 0.0, 0.0, 0.0, 0.0]  #: ∫T, ∫T², ∫|ψ|, ∫|ψ|², ∫|i|² (× 2, 3, 2, 3, 3)
        self._sum_i = 0j  #: ∫i_αβ dt
        self._sum_r = 0j  #: ∫i dt in the rotor frame (× 2)
        self._means = period_means
        if period_means:
            self._at = self._point(self.x)  #: the :data:`Point` where the next piece starts
            te, psi, i_r, _, rot = self._at
            i = i_r * rot
            self._avg = (
                te, te * te, psi, psi * psi, i.real, i.imag, abs(i) ** 2, i_r.real, i_r.imag
            )  # fmt: skip

    def _point(self, x: tuple[Any, ...]) -> Point:
        """The :data:`Point` of state ``x``: what the period means are taken of."""
        raise NotImplementedError

    def _coefficients(self, motor: Any) -> Any:
        """The coefficients of ``motor`` as this plant integrates them: a shaft a load machine
        holds is turned by no torque and loses nothing to friction in the equations."""
        c = self.coefficients.of(motor)
        return c if self._held is None else c._replace(inv_j=0.0, b=0.0)

    def _heat(self, t_winding: float, t_rotor: float) -> tuple[float, float]:
        """The machine at these temperatures (°C): its coefficients follow (R_s, R_r, ψ_f);
        returns (R_s, R_r) in Ω."""
        raise NotImplementedError

    def _rotor(self) -> tuple[int, int, float, float] | None:
        """Where a machine with rotor copper (an induction motor) holds ψ_s and i_s in its
        state, and L_s, 1/L_m: its rotor current (ψ_s - L_s·i_s)/L_m; None for a PMSM."""
        return None

    def _torque(self, x: tuple[Any, ...]) -> float:
        """The torque of state ``x``, N·m."""
        return self._point(x)[0]

    def _flux_ab(self, x: tuple[Any, ...]) -> complex:
        """The stator flux linkage in αβ of state ``x`` (Wb)."""
        raise NotImplementedError

    def _with_speed(self, x: tuple[Any, ...], omega_m: float) -> tuple[Any, ...]:
        w = self.speed_index
        return (*x[:w], omega_m, *x[w + 1 :])

    def _next_period(self) -> None:
        """Step k done: on to k + 1, its load (and the speed a load machine holds)."""
        self.k += 1
        self.load = self._load.at(self.k)
        if self._held is not None:
            self.x = self._with_speed(self.x, self._held.at(self.k))

    def _piece(self, x: tuple[Any, ...], u: Any, h: float) -> tuple[Any, ...]:
        """``x`` after ``h`` s under ``u`` (constant), in sub-steps of at most ``max_substep``,
        each added to the period's sums.

        Between a sub-step's ends each signal is taken as linear in time — the current in the
        rotor frame, where the fundamental stands still (a synchronous machine's; an induction
        motor's turns there at the slip frequency only) and the switching ripple is a ramp: ∫x
        by the trapezoid, ∫x² = h(a² + ab + b²)/3, and ∫i_αβ = ∫(i_0 + (i_1 - i_0)s)·e^{j(θ_0 +
        φs)} h ds = h·e^{jθ_0}·(i_0·E_0(φ) + (i_1 - i_0)·E_1(φ)) in closed form, φ the angle the
        rotor turns (E_0 = (e^{jφ} - 1)/(jφ), E_1 = ∫s·e^{jφs} ds, by their series)."""
        n = 1 if h <= self._max_substep else math.ceil(h / self._max_substep - 1e-9)
        dt = h / n  # what the integrator's own loop would take: the same floats
        integrate, coef, point, sums = self._integrate, self._coef, self._point, self._sums
        te0, f0, i0, th0, rot0 = self._at
        sum_i, sum_r = self._sum_i, self._sum_r
        for _ in range(n):
            x = integrate(0.0, x, u, coef, dt, 1)
            te1, f1, i1, th1, rot1 = point(x)
            sums[0] += dt * (te0 + te1)
            sums[1] += dt * (te0 * te0 + te0 * te1 + te1 * te1)
            sums[2] += dt * (f0 + f1)
            sums[3] += dt * (f0 * f0 + f0 * f1 + f1 * f1)
            phi = th1 - th0
            q = phi * phi
            if q < 0.01:  # |φ| < 0.1 rad: the series to φ⁴, within 2e-8
                e0 = complex(1.0 - q / 6.0 + q * q / 120.0, phi * (0.5 - q / 24.0))
                e1 = complex(0.5 - q / 8.0 + q * q / 144.0, phi * (1.0 / 3.0 - q / 30.0))
            else:
                e = complex(math.cos(phi), math.sin(phi))
                e0 = (e - 1.0) / complex(0.0, phi)
                e1 = e / complex(0.0, phi) + (e - 1.0) / q
            sum_i += dt * rot0 * (i0 * e0 + (i1 - i0) * e1)
            sum_r += dt * (i0 + i1)
            sums[4] += dt * (
                i0.real * (i0.real + i1.real) + i0.imag * (i0.imag + i1.imag)
                + i1.real * i1.real + i1.imag * i1.imag
            )  # fmt: skip
            te0, f0, i0, th0, rot0 = te1, f1, i1, th1, rot1
        self._at = (te0, f0, i0, th0, rot0)
        self._sum_i, self._sum_r = sum_i, sum_r
        return x

    def _advance(self, x: tuple[Any, ...], u: Any, h: float) -> tuple[Any, ...]:
        """``x`` after ``h`` s under ``u`` (constant): :meth:`_piece` when the period means are
        taken, else the integrator in sub-steps of at most ``max_substep``, in one call."""
        if self._means:
            return self._piece(x, u, h)
        n = 1 if h <= self._max_substep else math.ceil(h / self._max_substep - 1e-9)
        return self._integrate(0.0, x, u, self._coef, h, n)

    def _open_period(self) -> None:
        """Start the period's sums at the present state (which a test may have set by hand)."""
        self._at = self._point(self.x)

    def _close_period(self) -> None:
        """The sums of the period just integrated → its means (:data:`PERIOD_MEANS`)."""
        s = self._sums
        half, third = 0.5 / self.ts, 1.0 / (3.0 * self.ts)
        i, r = self._sum_i / self.ts, self._sum_r * half
        self._avg = (
            s[0] * half, s[1] * third, s[2] * half, s[3] * third, i.real, i.imag, s[4] * third,
            r.real, r.imag,
        )  # fmt: skip
        self._sums = [0.0, 0.0, 0.0, 0.0, 0.0]
        self._sum_i = self._sum_r = 0j

    def _i_ab(self, x: tuple[Any, ...]) -> complex:
        """The stator current in αβ of state ``x``."""
        raise NotImplementedError

    def _outputs(self) -> tuple[complex, float, float, float, complex, float]:
        """(i_s αβ, ω_m, θ_e wrapped, T_e, ψ_s αβ, θ_m) of the present state."""
        raise NotImplementedError

    def state(self) -> State:
        """The present state k as published (measured channels + truth)."""
        i, w, the, te, psi, th = self._outputs()
        ia, ib = i.real, i.imag
        m_ia, m_ib, m_w, m_the = (
            (ia, ib, w, the) if self.sensors is None else self.sensors.measure(i, th, w)
        )
        return new_record(
            State,
            (
                float(self.k),
                self.k * self.ts,
                m_ia,
                m_ib,
                m_w,
                m_the,
                self._u_dc_seen,
                te,
                psi.real,
                psi.imag,
                th,
                self.load,
                float(self._transitions),
                ia,
                ib,
                w,
                the,
                *self._avg,
            ),
        )

    def losses(self) -> Losses | None:
        """The present step's losses and temperatures (the period that ended at k, the
        temperatures at k); None where the plant books none (``plant.losses`` off)."""
        if self._ledger is None:
            return None
        self._ledger.flush()
        return new_record(Losses, (float(self.k), self.k * self.ts, *self._ledger.fields))

    def take_losses(self) -> np.ndarray:
        """The :class:`Losses` rows of the steps since the last take, up to the present one
        (from step 0; no rows where the plant books none): what the engines record, a batch at a
        time (the ledger's kernel books a thermal step's periods at once)."""
        if self._ledger is None:
            return np.empty((0, len(Losses._fields)))
        fields = self._ledger.take()
        out = np.empty((len(fields), len(Losses._fields)))
        out[:, 0] = np.arange(self.k + 1 - len(fields), self.k + 1)
        np.multiply(out[:, 0], self.ts, out=out[:, 1])
        out[:, 2:] = fields
        return out

    def step(self, command: Sequence[float]) -> State:
        """Apply ``command`` (a :class:`Command`, or its row of numbers) for one period."""
        if command[_K] != self.k:  # k as float
            raise ValueError(
                f"plant is at step {self.k} but got the command for step {command[_K]:g}"
            )
        pulses = command[PULSES]
        if self._pending is not None:  # the command acts later; an earlier one acts now
            self._pending.append(pulses)
            pulses = self._pending.popleft()
        if self._real_inverter:
            return self._step_real(pulses)
        segs, self.switches, self._transitions = segments(pulses, self.switches)
        ts = self.ts
        load = self.load  # constant over the period
        x = self.x
        volts = self._volts
        if self._means:
            self._open_period()
            for sw, frac in segs:
                x = self._piece(x, (volts[sw], load), frac * ts)
            self._close_period()
        else:
            coef, integrate, max_sub = self._coef, self._integrate, self._max_substep
            for sw, frac in segs:
                h = frac * ts
                n = 1 if h <= max_sub else math.ceil(h / max_sub - 1e-9)
                x = integrate(0.0, x, (volts[sw], load), coef, h, n)
        self.x = x
        self._next_period()
        return self.state()

    def _step_real(self, pulses: Sequence[float]) -> State:
        """One period through an inverter with dead time and device drops: during the dead time
        after each edge of a leg both its devices are off and the leg follows its current's sign
        (low while the current flows out of it, high while it flows in); every conducting device
        drops its on-state voltage against the current (``device_drop``, or its device's line
        v0 + r·|i| at its T_j). The signs and the currents are those at each segment's start;
        with losses each segment goes into the ledger."""
        ra, rb, rc, da, db, dc = pulses
        rises, falls, duties = (ra, rb, rc), (ra + da, rb + db, rc + dc), (da, db, dc)
        before = self.switches
        _, self.switches, self._transitions = segments(pulses, before)
        dead = self._dead
        cuts = {0.0, 1.0}
        windows: list[list[tuple[float, float]]] = []  # per leg: its dead intervals
        carry = self._carry
        for leg in range(3):
            r, f, d = rises[leg], falls[leg], duties[leg]
            edges = [e for e in (r, f) if d > 0.0 and 0.0 < e < 1.0]
            if (d > 0.0 and r == 0.0) != bool(before[leg]):
                edges.append(0.0)
            spans = [(0.0, carry[leg])] if carry[leg] > 0.0 else []
            carry[leg] = 0.0
            for e in edges:
                end = e + dead
                spans.append((e, min(end, 1.0)))
                carry[leg] = max(carry[leg], end - 1.0)
            windows.append(spans)
            cuts.update(edges)
            cuts.update(b for _, b in spans if b < 1.0)
        if self._means:
            self._open_period()
        ts, u_dc = self.ts, self.u_dc
        v0, slope, reverse = self._v0, self._r, self._reverse
        ledger = self._ledger
        trail: list[tuple[Any, ...]] = []  # the segments, for the ledger's reference
        # the segments' numbers, for the ledger's kernel (losses_kernel: SEG_WIDTH a segment)
        capture = ledger.capture if ledger is not None and ledger.batched else None
        k_psi, held = self._seg_extras
        load = self.load
        x = x_start = self.x
        points = sorted(cuts)
        for t0, t1 in zip(points, points[1:]):
            mid = 0.5 * (t0 + t1)
            i_ab = self._i_ab(x)
            currents = inverse_clarke(i_ab)
            legs = []
            highs = []
            devs = []
            drops = []
            for leg in range(3):
                cur = currents[leg]
                if any(a <= mid < b for a, b in windows[leg]):
                    high = cur < 0.0  # both devices off: a diode carries the current
                    dev = 4 * leg + (_D_HI if high else _D_LO)
                elif rises[leg] <= mid < falls[leg]:
                    high = True
                    dev = 4 * leg + (_T_HI if cur > 0.0 or reverse else _D_HI)
                else:
                    high = False
                    dev = 4 * leg + (_T_LO if cur < 0.0 or reverse else _D_LO)
                sign = (cur > 0.0) - (cur < 0.0)
                drop = sign * (v0[dev] + slope[dev] * abs(cur))  # the device's, against i
                legs.append(u_dc * high - drop)
                highs.append(high)
                devs.append(dev)
                drops.append(drop)
            if capture is not None:
                d0, d1, d2 = devs
                if k_psi is None and not held:
                    capture(((t1 - t0) * ts, i_ab.real, i_ab.imag, d0 + 16 * d1 + 256 * d2))
                else:
                    ps = x[k_psi] if k_psi is not None else 0j
                    capture((
                        (t1 - t0) * ts, i_ab.real, i_ab.imag, d0 + 16 * d1 + 256 * d2, ps.real,
                        ps.imag, self._torque(x) if held else 0.0,
                    ))  # fmt: skip
            elif ledger is not None:
                trail.append(((t1 - t0) * ts, x, i_ab, currents, highs, devs, drops))
            x = self._advance(x, (clarke(*legs), load), (t1 - t0) * ts)
        self.x = x
        if self._means:
            self._close_period()
        if capture is not None:
            w, th = self.speed_index, self.angle_index
            psi = self._flux_ab(x) if k_psi is not None or self._psi_wanted else 0j
            ledger.end_period(  # type: ignore[union-attr]
                len(points) - 1, (x_start[w], x[w]), x[th] - x_start[th], load, self._coef.b,
                psi,
            )  # fmt: skip
        elif ledger is not None:
            self._close_ledger(ledger, trail, x_start, x)
        self._next_period()
        return self.state()

    def _tail(self) -> tuple[float, ...]:
        """The present state as the ledger's kernel reads a segment's start (see
        :mod:`.losses_kernel`): where the last period's last segment ends."""
        x = self.x
        i_ab = self._i_ab(x)
        k_psi, held = self._seg_extras
        if k_psi is None and not held:
            return (0.0, i_ab.real, i_ab.imag, 0.0)
        ps = x[k_psi] if k_psi is not None else 0j
        te = self._torque(x) if held else 0.0
        return (0.0, i_ab.real, i_ab.imag, 0.0, ps.real, ps.imag, te)

    def _close_ledger(
        self, ledger: Ledger, trail: list[tuple[Any, ...]], x0: tuple[Any, ...], x: tuple[Any, ...]
    ) -> None:
        """The period from state ``x0`` to ``x`` in the segments ``trail`` ends: into the
        ledger (its losses, temperatures, fields)."""
        i_ab = self._i_ab(x)
        w, th = self.speed_index, self.angle_index
        ledger.close(
            trail, x, i_ab, inverse_clarke(i_ab), self._flux_ab(x), (x0[w], x[w]),
            x[th] - x0[th], self.load, self._coef.b,
        )  # fmt: skip


class InductionPlant(InverterPlant):
    """Induction motor (docs/physics.md#induction-motor); state (i_s, ψ_s, ω_m, θ_m), initially all
    zero (de-energised, at standstill)."""

    motor: InductionMotor
    coefficients = InductionCoefficients
    x0 = (0j, 0j, 0.0, 0.0)
    speed_index = _IM_W
    angle_index = _IM_TH
    default_integrator = staticmethod(induction_exact)

    def _heat(self, t_winding: float, t_rotor: float) -> tuple[float, float]:
        m, p = self.motor, self._ledger_params
        t_ref = p.motor_temperature
        r_s = resistance_at(m.r_s, t_winding, t_ref, COPPER_ALPHA)
        r_r = resistance_at(m.r_r, t_rotor, t_ref, p.cage_alpha)
        if self._cold is None:
            self._cold = dict(vars(m), sigma=m.sigma)
        hot = _Hot(self._cold)
        hot["r_s"], hot["r_r"] = r_s, r_r
        self._coef = self._coefficients(hot)
        return r_s, r_r

    def _rotor(self) -> tuple[int, int, float, float] | None:
        m = self.motor  # L_s, L_m do not follow temperature
        return _IM_PSI, _IM_I, m.l_s, 1.0 / m.l_m

    def _flux_ab(self, x: tuple[Any, ...]) -> complex:
        psi: complex = x[_IM_PSI]
        return psi

    def _i_ab(self, x: tuple[Any, ...]) -> complex:
        i: complex = x[_IM_I]
        return i

    def _point(self, x: tuple[Any, ...]) -> Point:
        i, psi = x[_IM_I], x[_IM_PSI]
        c = self._coef
        te = c.torque_k * (psi.real * i.imag - psi.imag * i.real)
        the = c.p * x[_IM_TH]
        rot = complex(math.cos(the), math.sin(the))
        return te, abs(psi), i * rot.conjugate(), the, rot

    def _outputs(self) -> tuple[complex, float, float, float, complex, float]:
        x = self.x
        i, psi, w, th = x[_IM_I], x[_IM_PSI], x[_IM_W], x[_IM_TH]
        c = self._coef
        te = c.torque_k * (psi.real * i.imag - psi.imag * i.real)
        return i, w, (c.p * th) % TWO_PI, te, psi, th


class PMSMPlant(InverterPlant):
    """PMSM (docs/physics.md#pmsm); state (i_dq, ω_m, θ_m), initially no current, at standstill, θ_m = 0. The
    published currents and flux are turned into αβ with θ_e = p·θ_m."""

    motor: PMSM
    coefficients = PMSMCoefficients
    x0 = (0j, 0.0, 0.0)
    speed_index = _PM_W
    angle_index = _PM_TH
    default_integrator = staticmethod(pmsm_rk4)

    def _heat(self, t_winding: float, t_rotor: float) -> tuple[float, float]:
        m, p = self.motor, self._ledger_params
        t_ref = p.motor_temperature
        r_s = resistance_at(m.r_s, t_winding, t_ref, COPPER_ALPHA)
        psi_f = resistance_at(m.psi_f, t_rotor, t_ref, p.magnet_alpha)
        if self._cold is None:
            self._cold = dict(vars(m))
        hot = _Hot(self._cold)
        hot["r_s"], hot["psi_f"] = r_s, psi_f
        self._coef = self._coefficients(hot)
        return r_s, 0.0

    def _flux_ab(self, x: tuple[Any, ...]) -> complex:
        c, i_dq, the = self._coef, x[_PM_I], self._coef.p * x[_PM_TH]
        psi_dq = complex(c.l_d * i_dq.real + c.psi_f, c.l_q * i_dq.imag)
        return psi_dq * complex(math.cos(the), math.sin(the))

    def _i_ab(self, x: tuple[Any, ...]) -> complex:
        the = self._coef.p * x[_PM_TH]
        i: complex = x[_PM_I] * complex(math.cos(the), math.sin(the))
        return i

    def _point(self, x: tuple[Any, ...]) -> Point:
        i_dq, the = x[_PM_I], self._coef.p * x[_PM_TH]
        i_d, i_q = i_dq.real, i_dq.imag
        _, _, _, l_d, l_q, psi_f, _, tk, _, _ = self._coef
        te = tk * i_q * (psi_f + (l_d - l_q) * i_d)
        psi = math.hypot(l_d * i_d + psi_f, l_q * i_q)
        return te, psi, i_dq, the, complex(math.cos(the), math.sin(the))

    def _outputs(self) -> tuple[complex, float, float, float, complex, float]:
        x = self.x
        i_dq, w, th = x[_PM_I], x[_PM_W], x[_PM_TH]
        c = self._coef
        the = c.p * th
        rot = complex(math.cos(the), math.sin(the))
        psi_dq = complex(c.l_d * i_dq.real + c.psi_f, c.l_q * i_dq.imag)
        te = c.torque_k * i_dq.imag * (c.psi_f + (c.l_d - c.l_q) * i_dq.real)
        return i_dq * rot, w, the % TWO_PI, te, psi_dq * rot, th


_ALL_STATES = [(a, b, c) for a in (0, 1) for b in (0, 1) for c in (0, 1)]


class _Hot(dict[str, Any]):
    """A machine's parameters at its temperatures, read as attributes by its coefficients'
    ``of`` (the motor dataclass's checks are not repeated every thermal step)."""

    def __getattr__(self, name: str) -> Any:
        return self[name]


#: machine type → plant class
PLANTS: dict[str, type[InverterPlant]] = {
    Machine.INDUCTION: InductionPlant,
    Machine.PMSM: PMSMPlant,
}


def make_plant(
    machine: str,
    motor: Any,
    *,
    ts: float,
    u_dc: float,
    load: StepProfile,
    max_substep: float,
    **real: Any,
) -> InverterPlant:
    """The plant of a machine type (every engine and the plant node alike); ``real``: the
    :class:`InverterPlant` settings of a real drive (delay, dead time, drops, sensors)."""
    return PLANTS[machine](motor, ts=ts, u_dc=u_dc, load=load, max_substep=max_substep, **real)
