"""An independent measure of a run's current distortion: the continuous waveform rebuilt between
the samples and its FFT over whole fundamental periods — what ``test_core_continuous.py`` holds
the project's THD_i cont to (docs/physics.md#continuous-time-figures).

The run is the project's own, in-process; beside every sub-step the plant integrates, the same
sub-step is integrated again in ``fine`` parts by the machine's integrator and the current logged
(the plant's trajectory is untouched). The log, linearly interpolated onto a uniform grid of
``points`` over exactly ``cycles`` periods of the fundamental (its frequency from the held speed
for a synchronous machine, from the stator flux's turn for an induction motor), goes through
``numpy.fft``; the THD is every bin but the fundamental's over it::

    .venv/bin/python test/continuous.py             # the table of docs/physics.md
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

import predictive_drive.core.runner as runner
from predictive_drive.config import apply_settings, load_scenario_text, resolve_scenario_path
from predictive_drive.core.machines.induction import InductionMotor
from predictive_drive.core.metrics import Metrics, compute_metrics
from predictive_drive.core.plant import InductionPlant, InverterPlant
from predictive_drive.core.scenario import Scenario


@dataclass(frozen=True)
class Rebuilt:
    """A run's continuous current: times (s), i_αβ (A) and ψ_s αβ (Wb) at each logged instant."""

    t: np.ndarray
    i: np.ndarray
    psi: np.ndarray


def scenario(name: str, settings: dict[str, Any]) -> Scenario:
    path = resolve_scenario_path(name)
    return load_scenario_text(apply_settings(path.read_text(), settings, path), str(path))


def _flux(plant: InverterPlant, x: tuple[Any, ...]) -> complex:
    if isinstance(plant, InductionPlant):
        return complex(x[1])
    c = plant._coef
    the = c.p * x[2]
    dq = complex(c.l_d * x[0].real + c.psi_f, c.l_q * x[0].imag)
    return dq * complex(math.cos(the), math.sin(the))


def run_rebuilt(sc: Scenario, *, fine: int = 8) -> tuple[Any, Rebuilt]:
    """The scenario's trace, and its current rebuilt at ``fine`` points per plant sub-step."""
    log_t: list[float] = []
    log_i: list[complex] = []
    log_psi: list[complex] = []
    build = runner.build

    def logging_build(s: Scenario) -> Any:
        parts = build(s)
        plant = parts.plant
        integrate, step = plant._integrate, plant.step
        at = [0.0]  # s into the present period

        def integrate_logged(t, x, u, coef, h, n):
            start = plant.k * s.ts + at[0]
            xs = x
            for j in range(fine):
                xs = integrate(0.0, xs, u, coef, h / fine, 1)
                log_t.append(start + (j + 1) * h / fine)
                log_i.append(plant._i_ab(xs))
                log_psi.append(_flux(plant, xs))
            at[0] += h
            return integrate(t, x, u, coef, h, n)  # the plant's own sub-step, as it takes it

        def step_logged(command):
            at[0] = 0.0
            return step(command)

        plant._integrate, plant.step = integrate_logged, step_logged
        log_t.append(0.0)
        log_i.append(plant._i_ab(plant.x))
        log_psi.append(_flux(plant, plant.x))
        return parts

    runner.build = logging_build
    try:
        trace = runner.run_inprocess(sc)
    finally:
        runner.build = build
    return trace, Rebuilt(np.array(log_t), np.array(log_i), np.array(log_psi))


def fft_thd(
    r: Rebuilt, t_start: float, t_end: float, *, f1: float | None = None, points: int = 2**18
) -> tuple[float, float, int]:
    """(THD, |I_1| A, cycles) of the rebuilt current over the whole fundamental periods from
    ``t_start`` that fit before ``t_end``; ``f1`` (Hz, signed by the turning direction) or, if
    None, the stator flux's mean turning rate over the window."""
    inside = (r.t >= t_start) & (r.t <= t_end)
    if f1 is None:
        angle = np.unwrap(np.angle(r.psi[inside]))
        f1 = float(np.polyfit(r.t[inside], angle, 1)[0]) / (2 * math.pi)
    cycles = int((t_end - t_start) * abs(f1))
    grid = t_start + np.arange(points) * (cycles / abs(f1) / points)
    wave = np.interp(grid, r.t, r.i.real) + 1j * np.interp(grid, r.t, r.i.imag)
    spectrum = np.fft.fft(wave) / points
    fund = abs(spectrum[cycles if f1 > 0 else points - cycles])
    rest = math.sqrt(max(0.0, float(np.sum(np.abs(spectrum) ** 2)) - fund * fund))
    return rest / fund, fund, cycles


def compare(name: str, khz: float, *, fine: int = 8) -> tuple[Metrics, float, float]:
    """The run of ``name`` at the carrier ``khz`` (ts = 1/f): its metrics, and the FFT's THD and
    |I_1| of its rebuilt current over the scenario's THD window."""
    sc = scenario(name, {"ts": 1e-3 / khz})
    trace, rebuilt = run_rebuilt(sc, fine=fine)
    log = sc.logger
    slips = isinstance(sc.plant.motor, InductionMotor)
    m = compute_metrics(
        trace,
        t_start=log.window_start,
        t_end=log.window_end,
        thd_window=tuple(log.thd_window),
        slips=slips,
    )
    f1 = None if slips else sc.plant.held_speed_rpm[-1] / 60.0 * sc.plant.motor.p
    thd, fund, _ = fft_thd(rebuilt, log.thd_window[0], log.thd_window[1], f1=f1)
    return m, thd, fund


def main(argv: list[str]) -> None:
    points = [("im_steady_foc", f) for f in (0.5, 2.0, 10.0, 20.0)] + [("ipmsm_steady_foc", 3.0)]
    if argv:
        points = [(a, float(b)) for a, b in (x.split(":") for x in argv)]
    print("scenario          f_sw kHz  THD_i cont %   FFT %    relative")
    for name, khz in points:
        m, thd, _ = compare(name, khz)
        print(
            f"{name:<17} {khz:>8g} {100 * m.i_thd_cont:>12.4f} {100 * thd:>8.4f} "
            f"{100 * (m.i_thd_cont / thd - 1):>+9.3f} %"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
