"""Run files: the CSV (version 1) every gyrotherm tool reads and the simulator writes.

Layout::

    # gyrotherm-run: 1
    # name: heat-05min            (optional "# key: value" metadata lines)
    time_s,temperature_c,rate_x_dps,rate_y_dps,rate_z_dps

* ``time_s``: seconds since power-on, strictly increasing.
* ``temperature_c``: the gyro's internal temperature sensor reading, °C.
* ``rate_<axis>_dps``: the static gyro's raw output, °/s; at least one axis.
* optional ``chamber_c`` (ambient, °C) and ``true_bias_<axis>_dps`` (simulation
  truth: tools read these only to score).
* any other column is kept in :attr:`Run.extra` when every value in it is a finite
  number, and ignored otherwise (text, blanks, ``nan``): tools never fail on it.

Known columns are strict: a blank, non-numeric or non-finite value in one is an
error naming file, line and column.

A malformed file raises :class:`gyrotherm.RunFileError` naming file, line, column and problem.
"""

from __future__ import annotations

import hashlib
import io
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import RunFileError
from gyrotherm.codecs._runbody import parse_body

RUN_FILE_VERSION = 1
AXES = ("x", "y", "z")
TEMPERATURE_PERIOD_KEY = "temperature_period_s"
"""Metadata key: the temperature sensor's refresh period, s (rows in between hold
the last reading)."""
_MAGIC = "gyrotherm-run"

FloatArray = NDArray[np.float64]


def _frozen(a: FloatArray) -> FloatArray:
    """A read-only float64 copy; an array that is already read-only float64 and owns
    its data (as the reader's columns) is taken as it is, not copied again."""
    if (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.base is None
            and not a.flags.writeable and a.flags.c_contiguous):
        return a
    out = np.array(a, dtype=np.float64, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class Run:
    """One recorded (or simulated) static run of a gyro.

    All arrays share one length and are read-only. ``rates_dps`` maps axis name
    (``"x"``, ``"y"``, ``"z"``) to raw output in °/s, in axis order.
    """

    name: str
    time_s: FloatArray
    temperature_c: FloatArray
    rates_dps: Mapping[str, FloatArray]
    chamber_c: FloatArray | None = None
    true_bias_dps: Mapping[str, FloatArray] = field(default_factory=dict)
    metadata: Mapping[str, str] = field(default_factory=dict)
    source: str = "<memory>"
    sha256: str = ""
    """sha256 of the file read, or of the measured columns for in-memory runs."""
    extra: Mapping[str, FloatArray] = field(default_factory=dict)
    """Other numeric columns, by header name (e.g. simulation truth
    ``true_temperature_c``, ``true_delta_t_c``); tools ignore them except to score."""

    def __post_init__(self) -> None:
        n = len(self.time_s)
        object.__setattr__(self, "time_s", _frozen(self.time_s))
        object.__setattr__(self, "temperature_c", _frozen(self.temperature_c))
        if not self.rates_dps:
            raise RunFileError(f"{self.source}: run {self.name!r} has no rate axis")
        rates = {a: _frozen(self.rates_dps[a]) for a in AXES if a in self.rates_dps}
        unknown = set(self.rates_dps) - set(AXES)
        if unknown:
            raise RunFileError(f"{self.source}: unknown rate axes {sorted(unknown)}")
        object.__setattr__(self, "rates_dps", rates)
        truth = {a: _frozen(v) for a, v in self.true_bias_dps.items()}
        object.__setattr__(self, "true_bias_dps", truth)
        extra = {k: _frozen(v) for k, v in self.extra.items()}
        object.__setattr__(self, "extra", extra)
        if self.chamber_c is not None:
            object.__setattr__(self, "chamber_c", _frozen(self.chamber_c))
        others = [self.temperature_c, *rates.values(), *truth.values(), *extra.values()]
        if self.chamber_c is not None:
            others.append(self.chamber_c)
        if any(len(a) != n for a in others):
            raise RunFileError(f"{self.source}: columns of run {self.name!r} differ in length")
        if not self.sha256:  # in-memory run: hash the measured columns
            h = hashlib.sha256()
            for a in (self.time_s, self.temperature_c, *rates.values()):
                h.update(a.tobytes())
            object.__setattr__(self, "sha256", h.hexdigest())

    @property
    def axes(self) -> tuple[str, ...]:
        """Axes with a rate column, in x, y, z order."""
        return tuple(self.rates_dps)

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0]) if len(self) else 0.0

    def temperature_period_s(self) -> float | None:
        """The temperature sensor's refresh period in s from the metadata key
        ``temperature_period_s`` (rows in between repeat the held reading), or
        None when the run does not record it. Raises :class:`RunFileError` naming
        the file, run and key when the value is not a finite number >= 0."""
        text = self.metadata.get(TEMPERATURE_PERIOD_KEY)
        if text is None:
            return None
        where = f"{self.source}: run {self.name!r} metadata {TEMPERATURE_PERIOD_KEY!r}"
        try:
            value = float(text)
        except ValueError:
            raise RunFileError(f"{where}: {text!r} is not a number of seconds") from None
        if not (np.isfinite(value) and value >= 0):
            raise RunFileError(f"{where}: must be a finite number of seconds >= 0, got {value!r}")
        return value

    def slice(self, start: int, stop: int) -> Run:
        """Rows ``start:stop`` as a new run (same name and metadata)."""
        return Run(
            name=self.name,
            time_s=self.time_s[start:stop],
            temperature_c=self.temperature_c[start:stop],
            rates_dps={a: v[start:stop] for a, v in self.rates_dps.items()},
            chamber_c=None if self.chamber_c is None else self.chamber_c[start:stop],
            true_bias_dps={a: v[start:stop] for a, v in self.true_bias_dps.items()},
            metadata=self.metadata,
            source=self.source,
            sha256=self.sha256,
            extra={k: v[start:stop] for k, v in self.extra.items()},
        )


def _columns(run: Run) -> list[tuple[str, FloatArray]]:
    cols: list[tuple[str, FloatArray]] = [
        ("time_s", run.time_s),
        ("temperature_c", run.temperature_c),
    ]
    cols += [(f"rate_{a}_dps", v) for a, v in run.rates_dps.items()]
    if run.chamber_c is not None:
        cols.append(("chamber_c", run.chamber_c))
    cols += [(f"true_bias_{a}_dps", v) for a, v in run.true_bias_dps.items()]
    cols += list(run.extra.items())
    return cols


def format_run(run: Run, *, exact: bool = False) -> str:
    """The run as CSV version 1 text: values with 9 significant digits (relative
    error ≤ 5·10⁻¹⁰), the time column exactly; with ``exact`` every column exactly
    (each with 17 digits where 9 do not read its values back bit for bit)."""
    buf = io.StringIO()
    buf.write(f"# {_MAGIC}: {RUN_FILE_VERSION}\n")
    meta = {"name": run.name, **{k: v for k, v in run.metadata.items() if k != "name"}}
    for key, value in meta.items():
        if "\n" in key or "\n" in str(value) or ":" in key:
            raise RunFileError(f"metadata key {key!r} or its value cannot be written")
        buf.write(f"# {key}: {value}\n")
    cols = _columns(run)
    buf.write(",".join(name for name, _ in cols) + "\n")
    data = np.column_stack([v for _, v in cols]) if len(run) else np.empty((0, len(cols)))
    fmt = [_round_trip_format(v) if exact or name == "time_s" else _VALUE_FORMAT
           for name, v in cols]
    np.savetxt(buf, data, delimiter=",", fmt=fmt)
    return buf.getvalue()


_VALUE_FORMAT = "%.9g"
"""9 significant digits: enough for any float32 reading to be told apart."""


def _round_trip_format(values: FloatArray) -> str:
    """``%.9g`` when it reads ``values`` back exactly (e.g. times of simulated and
    since-boot clocks), else ``%.17g`` (epoch stamps: 1.7e9 s at 9 digits would be
    10-s steps).

    Exact at 9 digits ⇔ each t is the double nearest n·10^-k with n < 10^9 integer, k
    its decimal places: checked with numpy rounding, not by formatting every row."""
    t = np.asarray(values, dtype=np.float64)
    mag = np.abs(t)
    places = 8 - np.floor(np.log10(np.where(mag > 0, mag, 1.0))).astype(np.int64)
    if t.size == 0:
        return _VALUE_FORMAT
    if not np.all(np.isfinite(t)) or np.any(np.abs(places) > 22):
        return "%.17g"
    scale = 10.0 ** np.abs(places)  # exact powers of ten (|places| ≤ 22)
    n = np.where(places >= 0, np.round(t * scale), np.round(t / scale))
    back = np.where(places >= 0, n / scale, n * scale)
    exact = bool(np.array_equal(back, t)) and bool(np.all(np.abs(n) < 1e9))
    return _VALUE_FORMAT if exact else "%.17g"


def write_run(run: Run, path: str | Path, *, exact: bool = False) -> Path:
    """Write ``run`` to ``path`` (CSV version 1; ``exact``: :func:`format_run`) and
    return the path."""
    p = Path(path)
    p.write_text(format_run(run, exact=exact), encoding="utf-8")
    return p


def read_run(path: str | Path) -> Run:
    """Read a run file; raise :class:`RunFileError` naming file, line and problem."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise RunFileError(f"{p}: cannot read run file: {exc.strerror}") from exc
    digest = hashlib.sha256(raw).hexdigest()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RunFileError(f"{p}: not UTF-8 text (byte {exc.start})") from exc
    del raw  # the bytes are not needed once decoded (half the memory of a large log)
    return parse_run(text, source=str(p), sha256=digest)


def _next_line(text: str, pos: int) -> tuple[str, int]:
    """The line starting at ``pos`` (without its end: \\n, \\r\\n or \\r) and where the
    next one starts (``len(text)`` at the end)."""
    n = text.find("\n", pos)
    r = text.find("\r", pos, n if n >= 0 else len(text))
    if r >= 0:  # \r or \r\n ends this line
        return text[pos:r], r + 2 if text.startswith("\r\n", r) else r + 1
    if n < 0:
        return text[pos:], len(text)
    return text[pos:n], n + 1


def parse_run(text: str, *, source: str = "<memory>", sha256: str = "") -> Run:
    """Parse CSV version 1 ``text``; ``source`` names it in errors.

    Only the few header lines are split off as Python strings; the body goes to
    numpy's C parser in one piece, so memory stays near the size of the text plus
    the columns (a 3.6·10⁶-row log is not turned into millions of line objects).
    """
    if not sha256:
        sha256 = hashlib.sha256(text.encode("utf-8")).hexdigest()
    first_line, pos = _next_line(text, 0)
    if not first_line.strip():
        raise RunFileError(f"{source}: line 1: empty file, expected '# {_MAGIC}: 1'")
    first = first_line.lstrip("#").strip()
    key, _, value = first.partition(":")
    if not first_line.startswith("#") or key.strip() != _MAGIC:
        raise RunFileError(f"{source}: line 1: expected '# {_MAGIC}: 1', got {first_line[:60]!r}")
    if value.strip() != str(RUN_FILE_VERSION):
        raise RunFileError(
            f"{source}: line 1: unsupported run file version {value.strip()!r} "
            f"(this gyrotherm reads version {RUN_FILE_VERSION})"
        )
    metadata: dict[str, str] = {}
    i = 1
    line, after = _next_line(text, pos)
    while pos < len(text) and line.startswith("#"):
        k, sep, v = line[1:].partition(":")
        if sep:
            metadata[k.strip()] = v.strip()
        i += 1
        pos = after
        line, after = _next_line(text, pos)
    if pos >= len(text):
        raise RunFileError(f"{source}: line {i + 1}: missing header row (time_s,temperature_c,...)")
    header = [h.strip() for h in line.split(",")]
    header_line = i + 1
    for required in ("time_s", "temperature_c"):
        if required not in header:
            raise RunFileError(f"{source}: line {header_line}: missing column {required!r}")
    if not any(f"rate_{a}_dps" in header for a in AXES):
        raise RunFileError(
            f"{source}: line {header_line}: missing rate column "
            "(need at least one of rate_x_dps, rate_y_dps, rate_z_dps)"
        )
    dupes = {h for h in header if header.count(h) > 1}
    if dupes:
        raise RunFileError(f"{source}: line {header_line}: duplicate columns {sorted(dupes)}")
    first_data_line = header_line + 1
    col = parse_body(text, after, header, _KNOWN, source=source, first_line=first_data_line)
    t = col["time_s"]
    steps = np.diff(t)
    if (steps <= 0).any():
        row = int(np.argmax(steps <= 0)) + 1
        raise RunFileError(
            f"{source}: line {first_data_line + row}: time_s not increasing "
            f"({t[row - 1]:g} then {t[row]:g})"
        )
    return Run(
        name=metadata.get("name", Path(source).stem),
        time_s=t,
        temperature_c=col["temperature_c"],
        rates_dps={a: col[f"rate_{a}_dps"] for a in AXES if f"rate_{a}_dps" in col},
        chamber_c=col.get("chamber_c"),
        true_bias_dps={a: col[f"true_bias_{a}_dps"] for a in AXES if f"true_bias_{a}_dps" in col},
        metadata=metadata,
        source=source,
        sha256=sha256,
        extra={h: col[h] for h in header if h in col and not _is_known(h)},
    )


_KNOWN = frozenset(
    {"time_s", "temperature_c", "chamber_c"}
    | {f"rate_{a}_dps" for a in AXES}
    | {f"true_bias_{a}_dps" for a in AXES}
)


def _is_known(column: str) -> bool:
    return column in _KNOWN
