"""Power semiconductors as their datasheets give them: the on-state characteristic of a
transistor and of its diode, their switching energies, their Foster networks and ratings
(docs/physics.md#losses-and-temperature).

A device file is JSON in a subset of upb-lea's transistordatabase format (what that format calls
``switch`` and ``diode``, ``channel``, ``e_on``/``e_off``/``e_rr``, ``thermal_foster``), so a file
of that database reads as it is; :func:`load_device` checks every field it reads and names the
file, the field and the allowed range of what it refuses. SI units throughout: V, A, J, K/W, s,
and °C for junction temperatures (as datasheets give them).

The models, per device at its junction temperature T_j:

- conduction: the output curve v(i) is replaced by its line v = v0 + r·i, fitted over the
  currents ``fit_current`` (least squares; a MOSFET's channel through the origin, v0 = 0), at each
  temperature the datasheet gives it; v0 and r are linear in T_j between those temperatures and
  held beyond them. A MOSFET's channel conducts both ways while it is on.
- switching: E(i) curves at the datasheet's test voltage V_ref and temperatures, piecewise linear
  in the commutated current (extrapolated from the end segments, never below 0), linear in T_j
  between the curves' temperatures (held beyond), and scaled to the DC link as
  (U_dc/V_ref)^K_v, K_v the file's ``voltage_exponent``.
"""

from __future__ import annotations

import json
import math
from bisect import bisect_left
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ConfigError

__all__ = [
    "DEVICE_TYPES",
    "Commutations",
    "Device",
    "EnergyTable",
    "Grid",
    "Line",
    "bracket",
    "commutations",
    "grid_value",
    "Part",
    "load_device",
    "parse_device",
]

#: the device types a file may name; the MOSFETs' channels conduct in reverse while on
DEVICE_TYPES = ("IGBT", "MOSFET", "SiC-MOSFET")
#: the key of this package's own fields in a device file (beside the database's)
OWN_KEY = "predictive_drive"
#: plausible ranges, so a value in another unit (mJ for J, mV for V, K for °C) is refused
T_J_RANGE = (-60.0, 250.0)  #: °C
ON_VOLTAGE_MAX = 50.0  #: V, an output curve's voltage
R_TH_MAX = 100.0  #: K/W
TAU_MAX = 1.0e4  #: s
#: a commutation lasting this long at the full test voltage and current is implausible: an
#: energy above V_ref·max(i, i_cont)·this is taken for a unit error (mJ given as J)
COMMUTATION_MAX_S = 1.0e-5
#: points each switching-energy curve is resampled to (a uniform current grid)
GRID_POINTS = 128
#: the switching energies each part must give (a curve against the current, ``graph_i_e``)
ENERGIES = {"switch": ("e_on", "e_off"), "diode": ("e_rr",)}
#: the keys the database's format defines in each object this loader reads (any other is a
#: misspelling and refused, naming the allowed ones); the loader reads only some of them
SWITCH_KEYS = ("comment", "manufacturer", "technology", "t_j_max", "thermal_foster", "channel",
               "e_on", "e_off", "e_on_meas", "e_off_meas", "linearized_switch", "r_channel_th",
               "charge_curve", "soa")  # fmt: skip
DIODE_KEYS = ("comment", "manufacturer", "technology", "t_j_max", "thermal_foster", "channel",
              "e_rr", "linearized_diode", "soa")  # fmt: skip
ENERGY_KEYS = ("dataset_type", "comment", "measurement_date", "measurement_testbench",
               "commutation_device", "t_j", "v_supply", "v_g", "v_g_off", "load_inductance",
               "commutation_inductance", "e_x", "r_g", "i_x", "graph_i_e", "graph_r_e",
               "graph_t_e")  # fmt: skip
ENERGY_DATASET_TYPES = ("graph_i_e", "single", "graph_r_e", "graph_t_e")
CHANNEL_KEYS = ("t_j", "v_g", "graph_v_i")
FOSTER_KEYS = ("r_th_vector", "r_th_total", "c_th_vector", "c_th_total", "tau_vector",
               "tau_total", "graph_t_rthjc")  # fmt: skip
OWN_KEYS = ("fit_current", "voltage_exponent")


@dataclass(frozen=True)
class Line:
    """A conduction line at one junction temperature: v = v0 + r·i (V, Ω), at ``t_j`` °C."""

    t_j: float
    v0: float
    r: float


@dataclass(frozen=True)
class EnergyTable:
    """One switching energy (E_on, E_off or E_rr) at the test voltage ``v_ref`` (V): per
    temperature ``t_j`` (°C, ascending) its values on the uniform current grid 0, ``step``,
    2·``step``, … (A, J), the last cell's slope carrying on beyond it."""

    v_ref: float
    t_j: tuple[float, ...]
    step: float
    values: tuple[tuple[float, ...], ...]

    def at_temperature(self, t_j: float, scale: float = 1.0) -> Grid:
        """The curve at ``t_j`` °C times ``scale`` as :func:`grid_value` reads it: linear in T_j
        between the curves, held beyond."""
        lo, hi, w = bracket(self.t_j, t_j)
        return (1.0 / self.step, self.values[lo], self.values[hi], w, scale)


#: an energy curve at one temperature: (1/grid step 1/A, the grid values at the bracketing
#: temperatures J, the upper one's weight, the scale of the DC link's voltage)
Grid = tuple[float, tuple[float, ...], tuple[float, ...], float, float]


def grid_value(grid: Grid | None, i: float) -> float:
    """The energy (J) of an :meth:`EnergyTable.at_temperature` at ``i`` A (0 for None): linear
    between grid points, the last cell's slope beyond, never below 0."""
    if grid is None:
        return 0.0
    inv, lo, hi, w, scale = grid
    x = abs(i) * inv
    k = int(x)
    if k > len(lo) - 2:
        k = len(lo) - 2
    f = x - k
    a = lo[k] + f * (lo[k + 1] - lo[k])
    e = (a + w * (hi[k] + f * (hi[k + 1] - hi[k]) - a)) * scale
    return e if e > 0.0 else 0.0


def bracket(temps: Sequence[float], t: float) -> tuple[int, int, float]:
    """(lower index, upper index, weight of the upper) of ``t`` among ascending ``temps``: linear
    between them, held at the ends."""
    n = len(temps)
    if n == 1 or t <= temps[0]:
        return 0, 0, 0.0
    if t >= temps[-1]:
        return n - 1, n - 1, 0.0
    hi = bisect_left(temps, t)
    lo = hi - 1
    return lo, hi, (t - temps[lo]) / (temps[hi] - temps[lo])


@dataclass(frozen=True)
class Part:
    """A device's transistor or diode: its rated junction temperature (°C), Foster network
    junction to case (R_i K/W, τ_i s; empty: it sits on the transistor's die, a MOSFET's body
    diode), conduction lines by temperature, switching energies by name, and the exponent of
    their voltage scaling."""

    t_j_max: float
    r_th: tuple[float, ...]
    tau: tuple[float, ...]
    lines: tuple[Line, ...]
    energies: dict[str, EnergyTable] = field(default_factory=dict)
    voltage_exponent: float = 1.0
    line_t: tuple[float, ...] = field(init=False, repr=False)  #: the lines' temperatures

    def __post_init__(self) -> None:
        object.__setattr__(self, "line_t", tuple(ln.t_j for ln in self.lines))

    def line(self, t_j: float) -> tuple[float, float]:
        """(v0 V, r Ω) at ``t_j`` °C."""
        lo, hi, w = bracket(self.line_t, t_j)
        a, b = self.lines[lo], self.lines[hi]
        return a.v0 + w * (b.v0 - a.v0), a.r + w * (b.r - a.r)

    def energy_grid(self, name: str, t_j: float, u_dc: float) -> Grid | None:
        """Switching energy ``name`` at ``t_j`` °C and ``u_dc`` V for :func:`grid_value`,
        scaled by (u_dc/V_ref)^K_v; None where the datasheet gives none."""
        table = self.energies.get(name)
        if table is None:
            return None
        return table.at_temperature(t_j, (u_dc / table.v_ref) ** self.voltage_exponent)

    def energy(self, name: str, i: float, t_j: float, u_dc: float) -> float:
        """Energy (J) of commutation ``name`` at ``i`` A, ``t_j`` °C and ``u_dc`` V; 0 for an
        energy the datasheet does not give."""
        return grid_value(self.energy_grid(name, t_j, u_dc), i)


@dataclass(frozen=True)
class Device:
    """A transistor with its anti-parallel diode, as one switch position of a leg."""

    name: str
    type: str  #: one of :data:`DEVICE_TYPES`
    manufacturer: str
    datasheet: str  #: where the datasheet is (its hyperlink)
    datasheet_date: str
    datasheet_version: str
    comment: str
    source: str  #: the file it was read from
    v_abs_max: float  #: V, the voltage class
    i_cont: float  #: A, rated continuous current
    r_th_cs: float  #: K/W, case to heatsink of one switch position
    fit_current: tuple[float, float]  #: A, the current range the conduction lines fit
    switch: Part
    diode: Part
    text: str = field(default="", repr=False, compare=False)  #: the file's text, as read

    @property
    def reverse_conducting(self) -> bool:
        """A MOSFET: its channel carries the reverse current while it is on."""
        return "MOSFET" in self.type

    @property
    def shared_die(self) -> bool:
        """The diode has no network of its own: it is the transistor's body diode, one die."""
        return not self.diode.r_th

    def rated_tj(self, position: str) -> float:
        """The rated junction temperature (°C) of a device position's part: ``t..`` the
        transistor's, ``d..`` the diode's (e.g. ``ta_hi``, ``dc_lo``)."""
        return (self.switch if position.startswith("t") else self.diode).t_j_max

    def check_voltage(self, u_dc: float, where: str) -> None:
        """ConfigError if the device's voltage class is below the DC link's ``u_dc`` V."""
        if self.v_abs_max < u_dc:
            raise ConfigError(
                f"{where}: {self.source}: v_abs_max {self.v_abs_max:g} V is below the DC link "
                f"(plant.u_dc {u_dc:g} V); a device of a voltage class of at least {u_dc:g} V"
            )


def load_device(path: str | Path) -> Device:
    """The device of a file (see the module's docstring); ConfigError names the file, the field
    and the allowed values of anything it refuses."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise ConfigError(f"{p}: cannot read the device file: {e.strerror}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{p}: not a device file (not UTF-8 text)") from None
    return parse_device(text, str(p))


def parse_device(text: str, source: str) -> Device:
    """:func:`load_device` of a file's text; ``source`` names it in errors."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise ConfigError(f"{source}: not JSON: {e.msg} at line {e.lineno}") from None
    r = _Reader(doc, source)
    kind = r.choice("type", DEVICE_TYPES)
    i_cont = r.number("i_cont", gt=0.0, unit="A")
    own = r.section(OWN_KEY, optional=True).only(OWN_KEYS)
    fit = own.numbers("fit_current", unit="A", gt=0.0, count=2, optional=True)
    fit_range = (fit[0], fit[1]) if fit else (0.1 * i_cont, i_cont)
    if fit_range[1] <= fit_range[0]:
        raise ConfigError(
            f"{source}: {OWN_KEY}.fit_current: {list(fit_range)} must rise (A, [from, to])"
        )
    exponents = own.section("voltage_exponent", optional=True).only(tuple(ENERGIES))
    mosfet = "MOSFET" in kind
    parts = {}
    for name, energies in ENERGIES.items():
        s = r.section(name).only(SWITCH_KEYS if name == "switch" else DIODE_KEYS)
        parts[name] = Part(
            t_j_max=s.number("t_j_max", ge=T_J_RANGE[0], le=T_J_RANGE[1], unit="°C"),
            **s.foster(optional=name == "diode"),
            lines=s.lines(fit_range, origin=mosfet and name == "switch", pick=name),
            energies={e: s.energies(e, i_cont) for e in energies},
            voltage_exponent=exponents.number(name, ge=0.0, le=3.0, optional=True, default=1.0),
        )
    return Device(
        name=r.text("name"),
        type=kind,
        manufacturer=r.text("manufacturer", optional=True),
        datasheet=r.text("datasheet_hyperlink", optional=True),
        datasheet_date=r.text("datasheet_date", optional=True),
        datasheet_version=r.text("datasheet_version", optional=True),
        comment=r.text("comment", optional=True),
        source=source,
        v_abs_max=r.number("v_abs_max", gt=0.0, unit="V"),
        i_cont=i_cont,
        r_th_cs=r.number("r_th_cs", ge=0.0, le=R_TH_MAX, unit="K/W"),
        fit_current=fit_range,
        switch=parts["switch"],
        diode=parts["diode"],
        text=text,
    )


class _Reader:
    """Reads the fields of one JSON object, each checked; errors name the file and the field's
    path (``switch.e_on[1].graph_i_e``)."""

    def __init__(self, doc: Any, source: str, path: str = "") -> None:
        if not isinstance(doc, dict):
            where = path or "the file"
            raise ConfigError(f"{source}: {where}: expected an object, got {_kind(doc)}")
        self.doc = doc
        self.source = source
        self.path = path

    def where(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def fail(self, key: str, why: str) -> ConfigError:
        return ConfigError(f"{self.source}: {self.where(key)}: {why}")

    def only(self, allowed: tuple[str, ...]) -> _Reader:
        """This reader, after refusing any key of its object not in ``allowed`` (a misspelt
        field would otherwise read as absent)."""
        for key in self.doc:
            if key not in allowed:
                raise self.fail(key, f"unknown field; the allowed ones: {', '.join(allowed)}")
        return self

    def get(self, key: str, optional: bool) -> Any:
        value = self.doc.get(key)
        if value is None and not optional:
            raise self.fail(key, "missing field")
        return value

    def section(self, key: str, optional: bool = False) -> _Reader:
        value = self.get(key, optional)
        return _Reader({} if value is None else value, self.source, self.where(key))

    def text(self, key: str, optional: bool = False) -> str:
        value = self.get(key, optional)
        if value is None:
            return ""
        if not isinstance(value, str):
            raise self.fail(key, f"expected text, got {_kind(value)}")
        return value

    def choice(self, key: str, choices: tuple[str, ...]) -> str:
        value = self.text(key)
        if value not in choices:
            raise self.fail(key, f"{value!r} is not one of {', '.join(choices)}")
        return value

    def number(
        self,
        key: str,
        *,
        gt: float | None = None,
        ge: float | None = None,
        le: float | None = None,
        unit: str = "",
        optional: bool = False,
        default: float = math.nan,
    ) -> float:
        value = self.get(key, optional)
        if value is None:
            return default
        return _checked(value, lambda why: self.fail(key, why), gt=gt, ge=ge, le=le, unit=unit)

    def numbers(
        self,
        key: str,
        *,
        unit: str,
        gt: float | None = None,
        ge: float | None = None,
        le: float | None = None,
        count: int | None = None,
        optional: bool = False,
    ) -> list[float]:
        value = self.get(key, optional)
        if value is None:
            return []
        if not isinstance(value, list) or not value or (count and len(value) != count):
            n = f"{count} numbers" if count else "a list of numbers"
            raise self.fail(key, f"expected {n}, got {_kind(value)}")
        return [
            _checked(
                v, lambda why, j=j: self.fail(f"{key}[{j}]", why), gt=gt, ge=ge, le=le, unit=unit
            )
            for j, v in enumerate(value)
        ]

    def items(self, key: str, optional: bool = False) -> list[_Reader]:
        value = self.get(key, optional)
        if value is None:
            return []
        if not isinstance(value, list) or not value:
            raise self.fail(key, f"expected a list of datasets, got {_kind(value)}")
        return [_Reader(v, self.source, f"{self.where(key)}[{j}]") for j, v in enumerate(value)]

    def foster(self, optional: bool) -> dict[str, tuple[float, ...]]:
        """The Foster network junction to case (``thermal_foster``: r_th_vector K/W,
        tau_vector s); empty where it is optional and absent."""
        value = self.get("thermal_foster", optional)
        if value is None or (optional and isinstance(value, dict) and not value.get("r_th_vector")):
            return {"r_th": (), "tau": ()}
        f = self.section("thermal_foster").only(FOSTER_KEYS)
        r = f.numbers("r_th_vector", unit="K/W", gt=0.0, le=R_TH_MAX)
        tau = f.numbers("tau_vector", unit="s", gt=0.0, le=TAU_MAX)
        if len(r) != len(tau):
            raise self.fail(
                "thermal_foster", f"r_th_vector has {len(r)} terms, tau_vector {len(tau)}"
            )
        return {"r_th": tuple(r), "tau": tuple(tau)}

    def lines(self, fit: tuple[float, float], *, origin: bool, pick: str) -> tuple[Line, ...]:
        """The conduction line at each temperature of ``channel``: per temperature the curve at
        the highest gate voltage (the transistor on) or, for a diode, the lowest (its gate off)."""
        chosen: dict[float, tuple[float, _Reader]] = {}
        for c in self.items("channel"):
            c.only(CHANNEL_KEYS)
            t_j = c.number("t_j", ge=T_J_RANGE[0], le=T_J_RANGE[1], unit="°C")
            v_g = c.number("v_g", optional=True, default=0.0, unit="V")
            rank = v_g if pick == "switch" else -v_g
            if t_j not in chosen or rank > chosen[t_j][0]:
                chosen[t_j] = (rank, c)
        out = []
        for t_j in sorted(chosen):
            c = chosen[t_j][1]
            v, i = c.curve("graph_v_i", x_max=ON_VOLTAGE_MAX, x_unit="V", y_unit="A")
            out.append(_fit_line(t_j, v, i, fit, origin, c.fail))
        return tuple(out)

    def curve(
        self, key: str, *, x_max: float, x_unit: str, y_unit: str
    ) -> tuple[list[float], list[float]]:
        """A curve ``[[x...], [y...]]``: x rising, y not falling (an output curve) or any
        (set by the caller), both >= 0."""
        value = self.get(key, False)
        if not (
            isinstance(value, list) and len(value) == 2 and all(isinstance(a, list) for a in value)
        ):
            raise self.fail(key, f"expected [[x, ...], [y, ...]], got {_kind(value)}")
        xs, ys = value
        if len(xs) != len(ys) or len(xs) < 2:
            raise self.fail(key, f"{len(xs)} x values and {len(ys)} y values: need equal, >= 2")
        x = [
            _checked(a, lambda why, j=j: self.fail(key, f"point {j}: {why}"), ge=0.0, le=x_max,
                     unit=x_unit)
            for j, a in enumerate(xs)
        ]  # fmt: skip
        y = [
            _checked(b, lambda why, j=j: self.fail(key, f"point {j}: {why}"), ge=0.0, unit=y_unit)
            for j, b in enumerate(ys)
        ]
        for j in range(1, len(x)):
            if not x[j] > x[j - 1]:
                raise self.fail(
                    key,
                    f"not monotonic: point {j} at {x[j]:g} {x_unit} after {x[j - 1]:g} {x_unit} "
                    f"(the {x_unit} values must rise)",
                )
        return x, y

    def energies(self, name: str, i_cont: float) -> EnergyTable:
        """The curves of switching energy ``name`` (datasets ``graph_i_e``) at the highest test
        voltage given, as an :class:`EnergyTable`; refused where the file gives none (a part
        without the energy would book 0 J for every such commutation)."""
        sets = []
        for d in self.items(name):
            d.only(ENERGY_KEYS)
            if d.doc.get("dataset_type", "graph_i_e") != "graph_i_e":
                d.choice("dataset_type", ENERGY_DATASET_TYPES)
                continue  # a single point, energy against gate resistance or time: not used
            v_ref = d.number("v_supply", gt=0.0, unit="V")
            t_j = d.number("t_j", ge=T_J_RANGE[0], le=T_J_RANGE[1], unit="°C")
            i, e = d.curve("graph_i_e", x_max=math.inf, x_unit="A", y_unit="J")
            for j, (a, b) in enumerate(zip(i, e)):
                limit = v_ref * max(a, i_cont) * COMMUTATION_MAX_S
                if b > limit:
                    raise d.fail(
                        "graph_i_e",
                        f"point {j}: {b:g} J at {a:g} A is more than {v_ref:g} V x "
                        f"{max(a, i_cont):g} A over {COMMUTATION_MAX_S * 1e6:g} us "
                        f"({limit:g} J): energies are in J (not mJ)",
                    )
            sets.append((v_ref, t_j, i, e))
        if not sets:
            raise self.fail(
                name,
                "no dataset of dataset_type graph_i_e (the energy against the current, "
                "[[A, ...], [J, ...]]): the only kind the losses read",
            )
        v_ref = max(s[0] for s in sets)
        at_v = sorted((s for s in sets if s[0] == v_ref), key=lambda s: s[1])
        temps = [s[1] for s in at_v]
        if len(set(temps)) != len(temps):
            raise self.fail(name, f"two curves at {v_ref:g} V for one temperature")
        top = max(s[2][-1] for s in at_v)
        step = top / (GRID_POINTS - 1)
        values = tuple(
            tuple(_interp(k * step, i, e) for k in range(GRID_POINTS)) for _, _, i, e in at_v
        )
        return EnergyTable(v_ref, tuple(temps), step, values)


def _interp(x: float, xs: list[float], ys: list[float]) -> float:
    """y(x) of a piecewise-linear curve, the end segments' slopes carrying on, never below 0."""
    j = 1
    while j < len(xs) - 1 and xs[j] < x:
        j += 1
    x0, x1, y0, y1 = xs[j - 1], xs[j], ys[j - 1], ys[j]
    return max(0.0, y0 + (x - x0) * (y1 - y0) / (x1 - x0))


def _fit_line(
    t_j: float,
    v: list[float],
    i: list[float],
    fit: tuple[float, float],
    origin: bool,
    fail: Any,
) -> Line:
    """The least-squares line v = v0 + r·i (through the origin where ``origin``) of an output
    curve sampled at 16 currents across ``fit``."""
    if not i[-1] >= fit[1] or fit[0] < i[0]:
        raise fail(
            "graph_v_i",
            f"the curve spans {i[0]:g}-{i[-1]:g} A at {t_j:g} °C; the conduction line is "
            f"fitted over {fit[0]:g}-{fit[1]:g} A (predictive_drive.fit_current)",
        )
    for j in range(1, len(i)):
        if i[j] < i[j - 1]:
            raise fail(
                "graph_v_i",
                f"not monotonic: the current falls from {i[j - 1]:g} A to {i[j]:g} A at point "
                f"{j} (an output curve's current rises with its voltage)",
            )
    # v(i): the inverse of the rising curve, at currents across the range
    cs = [fit[0] + (fit[1] - fit[0]) * k / 15 for k in range(16)]
    vs = [_inverse(c, v, i) for c in cs]
    if origin:
        r = sum(c * a for c, a in zip(cs, vs)) / sum(c * c for c in cs)
        return Line(t_j, 0.0, r)
    n = len(cs)
    mc, mv = sum(cs) / n, sum(vs) / n
    r = sum((c - mc) * (a - mv) for c, a in zip(cs, vs)) / sum((c - mc) ** 2 for c in cs)
    v0 = mv - r * mc
    if v0 < 0.0 or r < 0.0:
        raise fail(
            "graph_v_i",
            f"at {t_j:g} °C its line over {fit[0]:g}-{fit[1]:g} A is v = {v0:.4g} V + "
            f"{r:.4g} Ohm x i: a negative threshold or slope (not an output curve)",
        )
    return Line(t_j, v0, r)


def _inverse(c: float, v: list[float], i: list[float]) -> float:
    """The voltage at current ``c`` of a curve whose current rises (flat stretches skipped)."""
    for j in range(1, len(i)):
        if i[j] >= c and i[j] > i[j - 1]:
            return v[j - 1] + (c - i[j - 1]) * (v[j] - v[j - 1]) / (i[j] - i[j - 1])
    raise AssertionError("checked by the caller: the curve reaches the current")


def _checked(
    value: Any,
    fail: Any,
    *,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
    unit: str = "",
) -> float:
    """``value`` as a float if it is a finite number in range, else ``fail(why)`` raised."""
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if ok and gt is not None:
        ok = value > gt
    if ok and ge is not None:
        ok = value >= ge
    if ok and le is not None:
        ok = value <= le
    if not ok:
        parts = [f"> {gt:g}" if gt is not None else "", f">= {ge:g}" if ge is not None else ""]
        parts.append(f"<= {le:g}" if le is not None and math.isfinite(le) else "")
        rng = " and ".join(p for p in parts if p)
        unit_text = f" {unit}" if unit else ""
        raise fail(f"{value!r} is not a finite number{' ' + rng if rng else ''}{unit_text}")
    return float(value)


def _kind(value: Any) -> str:
    return "nothing" if value is None else f"{type(value).__name__} {value!r}"[:60]


# -- One leg's commutation, as a controller predicts its energy (the loss-aware cost of the
# finite-control-set laws, docs/physics.md#a-loss-aware-switching-cost): the plant's rule of which
# device turns on or off at a change of level (docs/physics.md#the-devices), at a given current --


@dataclass(frozen=True)
class Commutations:
    """A device's switching energies at one junction temperature and DC-link voltage, by what
    a leg's change of level does to the current ``i`` (A, out of the leg): where the change
    makes a transistor take the current forward — the leg rising with i > 0, falling with
    i < 0 — its E_on and the recovery E_rr of the other position's diode; else the transistor
    that carried it turns off, E_off (a change the current makes itself, a diode taking over
    or a MOSFET's reverse channel, costs nothing more)."""

    e_on: Grid | None
    e_off: Grid | None
    e_rr: Grid | None

    def taking(self, i: float) -> float:
        """E_on + E_rr (J) at ``i`` A: a transistor takes the current."""
        return grid_value(self.e_on, i) + grid_value(self.e_rr, i)

    def leaving(self, i: float) -> float:
        """E_off (J) at ``i`` A: the transistor that carried the current turns off."""
        return grid_value(self.e_off, i)

    def energy(self, i: float, *, rising: bool) -> float:
        """The energy (J) of a leg's change of level (``rising``: low to high) carrying ``i``
        A out of the leg."""
        takes = i > 0.0 if rising else i < 0.0
        return self.taking(i) if takes else self.leaving(i)


def commutations(device: Device, *, t_j: float, u_dc: float) -> Commutations:
    """The switching energies of ``device`` at ``t_j`` °C and ``u_dc`` V, by commutation."""
    return Commutations(
        device.switch.energy_grid("e_on", t_j, u_dc),
        device.switch.energy_grid("e_off", t_j, u_dc),
        device.diode.energy_grid("e_rr", t_j, u_dc),
    )
