"""Learning a calibration in the field: the daemon's ``[learn]`` mode, one per IMU.

**What is collected.** At every power-on the pipeline takes (t_on = 0,
:mod:`gyrotherm.daemon._compensation`) a :class:`WarmupAccumulator` starts. Each
temperature frame gives one row: the estimator's T̂ and ΔT̂, t_on, and per axis the mean
raw rate of the rate frames since the previous temperature frame. Rows wait in a block
of ``rest_window_s``; a block is **at rest** when no rate frame in it exceeds
``max_rate_dps`` in magnitude and the rate frames' standard deviation is at most
``max_std_dps`` on every axis; its rows then go into the accumulator (which uses those
from ``SETTLE_S`` on: :mod:`gyrotherm.compensation._learnstate`). The first block in
motion ends the warm-up (nothing after it is learnt, as offline). Memory is the
accumulator's fixed sums plus one block of rows.

**When a warm-up ends** (``warmup_window_s`` after power-on, motion, the next power-on,
or the daemon stopping) it is **used** when it has at least ``min_rest_s`` of rows at
rest after ``SETTLE_S``, else left out as ``motion`` (motion ended it) or
``too_short``. Not learnt at all, and counted: a warm-up cut by a **clock jump** (a
time-base change of the sensor's stamps, or a silence the wall clock did not see:
``clock_jump``; what follows the jump is not a power-on the daemon can trust either,
so nothing is collected until the next real one), and a daemon start that is not the
start of a warm-up it saw (``restart``, ``missed_start``; below).

**The daemon's first frame.** The pipeline takes the first accepted temperature frame
after the daemon starts as a power-on (unless a saved effects state is taken back: the
gyro kept running, ``restart``). The learner learns it only when it is one the daemon
saw from its start. The stamps are the CAN frames' time stamps (the DBC has no time
signal): on SocketCAN the host's receive time (wall clock), from a log, the virtual bus
or the simulator the sender's, there the gyro's own time since its power-on (the
simulator's run time). Which one, the stamp's size says (``codecs._candump_run``'s
convention, :data:`DEVICE_CLOCK_LIMIT_S`):

* **Stamps below 10⁶ s are the gyro's time since its power-on**, so the first stamp t
  *is* the time since power-on and the rule is about it, not about how recently the
  state was saved (a ``kill -9`` saves nothing; saves come every :data:`SAVE_PERIOD_S`
  while collecting). t ≤ :data:`FIRST_FRAME_MAX_S`: a power-on seen from its start,
  learnt. Later: not learnt, as ``restart`` when the saved run goes on (t ≥ the saved
  ``last_time_s`` and the stamps advanced at least as much as the wall clock since that
  frame, less ``power_on_gap_s``: the gyro's clock did not restart), else as
  ``missed_start`` (the gyro power-cycled while the daemon was down, or ran before a
  first start: the warm-up's first part, its start temperature and its t_on are
  unknown).
* **Larger stamps (a host's clock) say nothing about the gyro's power-on.** ``restart``
  when the first stamp continues the saved ``last_time_s`` within ``power_on_gap_s``
  (every frame updates it; a stop saves it, a ``kill -9`` does not), or, after a
  daemon that did not stop (killed, crashed, the power cut: the state still holds the
  latest power-on's stamp ``power_on_time_s``, saved at once and cleared by a clean
  stop), when it is within ``warmup_window_s`` of that power-on: a restart, or a power
  cycle the daemon could not see, inside a warm-up it cannot learn either way. Else a
  power-on, learnt.

**Deciding.** A used warm-up is added to the :class:`LearnState` (at most 256, the
oldest dropped), the state file is written, and :func:`decide` runs on a worker thread
against the calibration in use (the adopted learnt one, else the configured one, else
none). Only when it adopts, the learnt calibration is written atomically with its
provenance (:mod:`gyrotherm.daemon._learn_store`); the swap itself happens on the
frame thread, between two frames (:meth:`Learner.poll` at the next temperature frame
or housekeeping, whichever comes first): no frame is dropped. A failed write adopts
nothing and keeps the previous file.

**Progress** (:attr:`Learner.progress`, the state message's ``learn``) is rebuilt only
when something changes, so the state message only packs it.
"""

from __future__ import annotations

import concurrent.futures
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from gyrotherm import __version__
from gyrotherm._errors import CalibrationError
from gyrotherm.codecs._wire import LearnProgress
from gyrotherm.compensation import Calibration, parse_calibration
from gyrotherm.compensation._learn import (
    SETTLE_S,
    Decision,
    WarmupStats,
    decide,
    learnt_calibration,
)
from gyrotherm.compensation._learnstate import LearnState, WarmupAccumulator
from gyrotherm.daemon import _learn_store as store
from gyrotherm.daemon._learn_config import LearnConfig
from gyrotherm.estimators import EstimatorConfig, TemperatureEstimate

log = logging.getLogger("gyrotherm.daemon")

#: Seconds (monotonic) between saves of the learning state while a warm-up is collected,
#: besides those at its power-on, at its end and at shutdown.
SAVE_PERIOD_S = 60.0
#: Stamps in [0, this) are the gyro's own time since its power-on, larger ones a host's
#: clock (the convention of :data:`gyrotherm.codecs._candump_run.POWER_ON_LIMIT_S`).
DEVICE_CLOCK_LIMIT_S = 1e6
#: The latest a first frame on the gyro's own clock may be stamped and still start a
#: warm-up the daemon saw (rows are used from SETTLE_S after power-on), s.
FIRST_FRAME_MAX_S = SETTLE_S
#: Most rows one rest block holds before it is judged early (memory bound).
MAX_BLOCK_ROWS = 20_000
_NAN3 = (math.nan, math.nan, math.nan)


def _utc(time_s: float) -> str:
    return datetime.fromtimestamp(time_s, UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


@dataclass(frozen=True)
class _Outcome:
    """What the worker found for one set of warm-ups."""

    decision: Decision | None
    error: str = ""
    calibration: Calibration | None = None
    calibration_id: str = ""
    time_s: float = math.nan


class Learner:
    """One IMU's learning (module docstring). Not thread-safe: every method but the
    worker's job runs on the thread that processes the frames."""

    # the row (rate frames since the last temperature frame) and the rest block
    _row_n: int
    _rx: float
    _ry: float
    _rz: float
    _rows: list[tuple[float, float, float, tuple[float, float, float]]]
    _block_start: float
    _bn: int
    _bs: list[float]
    _bq: list[float]
    _bmax: float

    def __init__(self, config: LearnConfig, *, vehicle: str, sensor: str, state_dir: Path,
                 power_on_gap_s: float, estimator: EstimatorConfig,
                 axes: tuple[str, ...] = ("x", "y", "z"), device_id: str | None = None,
                 device_mismatch: str = "refuse", background: bool = True,
                 clock: Callable[[], float] = time.time) -> None:
        self.config = config
        self.vehicle, self.sensor, self.axes = vehicle, sensor, axes
        self.state_path = store.state_path(state_dir, vehicle, sensor)
        self.learnt_path = store.learnt_path(state_dir, vehicle, sensor)
        self._gap_s = power_on_gap_s
        self._device = (device_id, device_mismatch)
        self.estimator = estimator
        self._clock = clock
        self.record = store.LearnRecord(vehicle, sensor, LearnState(axes))
        self.current: Calibration | None = None
        self.current_id = ""
        self.adopted = False
        self.refused: list[str] = []
        """Why a file in state_dir was refused at start (empty: none)."""
        self.on_adopt: Callable[[Calibration, str], None] | None = None
        self._pool = (concurrent.futures.ThreadPoolExecutor(1, f"learn-{sensor}")
                      if background else None)
        self._future: concurrent.futures.Future[_Outcome] | None = None
        self._done: _Outcome | None = None
        self._again = False
        self._last_save = -math.inf
        self._last_left_out = ""
        self._first = True
        self._acc: WarmupAccumulator | None = None
        self._used_t = [math.inf, -math.inf]  # first and last t_on of the rows used, s
        self._reset_row()
        self._reset_block()
        self.progress = self._progress()

    # --- start and stop ------------------------------------------------------------------

    def start(self, configured: Calibration | None, configured_id: str
              ) -> tuple[Calibration | None, str]:
        """Read state_dir; the calibration to run with (an adopted learnt one that is
        valid, else ``configured``) and its id."""
        try:
            record = store.load_record(self.state_path, vehicle=self.vehicle,
                                       sensor=self.sensor, axes=self.axes)
        except CalibrationError as exc:
            self.refused.append(str(exc))
            store.quarantine(self.state_path, f"learning starts afresh: {exc}")
            record = None
        if record is not None:
            self.record = record
        use, use_id = configured, configured_id
        try:
            learnt = store.load_learnt(self.learnt_path, vehicle=self.vehicle,
                                       sensor=self.sensor, device_id=self._device[0],
                                       device_mismatch=self._device[1])
        except CalibrationError as exc:
            self.refused.append(str(exc))
            store.quarantine(self.learnt_path, "the configured calibration "
                             f"({configured_id or 'none'}) is used: {exc}")
            learnt = None
        if learnt is not None:
            use, use_id = learnt
            self.adopted = True
            took = use.provenance.get("adopted_time_s")
            if (self.record.adopted or {}).get("calibration_id") != use_id:  # the file rules
                self.record.adopted = {"time_s": float(took) if isinstance(
                    took, int | float) else math.nan, "calibration_id": use_id}
            log.info("%s: learnt calibration %s in use (%s)", self.sensor, use_id,
                     self.learnt_path)
        self.set_current(use, use_id)
        if self.record.learn.warmups:
            self._submit()  # the validation figures of what is known (may adopt, inline)
        self.progress = self._progress()
        return self.current, self.current_id

    def set_current(self, calibration: Calibration | None, calibration_id: str) -> None:
        """The calibration in use (what a candidate must beat)."""
        self.current, self.current_id = calibration, calibration_id
        if calibration is not None:
            self.estimator = calibration.estimator

    def shutdown(self) -> None:
        """The daemon stops: the warm-up ends here, the state is saved; a decision in
        flight is waited for (its adoption is written, and taken at the next start)."""
        self._close("shutdown")
        if self._future is not None:
            try:
                self._future.result(timeout=60.0)
            except Exception:
                log.exception("%s: learning decision failed at shutdown", self.sensor)
        self.poll()
        self.record.power_on_time_s = math.nan  # a clean stop: last_time_s is exact
        self._save()
        if self._pool is not None:
            self._pool.shutdown(wait=True)

    # --- the frame thread's hooks ----------------------------------------------------------

    def power_on(self, time_s: float, first: bool, time_base: bool, restored: bool,
                 receive_time_s: float = math.nan) -> None:
        """The pipeline took a power-on at sensor time ``time_s``, received at wall-clock
        ``receive_time_s`` (module docstring: which power-ons are learnt)."""
        self._close("clock_jump" if time_base else "power_on")
        was_first, self._first = self._first, False
        if restored:
            skip = "restart"
        elif time_base:
            skip = "clock_jump"
        elif was_first:
            skip = self._first_frame(time_s, receive_time_s)
        else:
            skip = ""
        rec = self.record
        rec.last_time_s, rec.last_wall_s = time_s, receive_time_s
        if skip == "restart":
            self._left_out("restart")
            log.info("%s: learning: the gyro kept running across the restart (t = %r s); "
                     "its warm-up is not learnt", self.sensor, time_s)
        elif skip == "missed_start":
            self._left_out("missed_start")
            log.info("%s: learning: the first frame is stamped %.1f s after the gyro's "
                     "power-on, which the daemon did not see (it was down or started "
                     "late); this warm-up is not learnt", self.sensor, time_s)
        elif skip:
            log.warning("%s: learning: a clock jump (time base change at t = %r s); nothing "
                        "is collected until the next power-on", self.sensor, time_s)
        else:
            rec.power_ons += 1
            self._acc = WarmupAccumulator(
                f"power-on {rec.power_ons} at {_utc(self._clock())}", self.axes)
            self._used_t = [math.inf, -math.inf]
        if self._acc is not None:
            rec.power_on_time_s = time_s
        self._reset_row()
        self._reset_block()
        if was_first or self._acc is not None:  # what a killed daemon's successor reads
            self._save()
        self.progress = self._progress()

    def _first_frame(self, time_s: float, wall_s: float) -> str:
        """Whether the daemon's first frame (no effects state taken back) starts a warm-up
        it sees (""), continues one it cannot learn (``restart``) or is late in a power-on
        it did not see (``missed_start``): module docstring."""
        rec = self.record
        last, since = rec.last_time_s, rec.power_on_time_s
        if 0.0 <= time_s < DEVICE_CLOCK_LIMIT_S:  # the gyro's own time since power-on
            if time_s <= FIRST_FRAME_MAX_S:
                return ""
            # the stamp clock restarted since the save (the gyro power-cycled) when it is
            # behind the saved stamp, or advanced less than the wall clock by over the gap
            wall_gap = (wall_s - rec.last_wall_s) - (time_s - last)
            return ("restart" if time_s >= last and not wall_gap > self._gap_s
                    else "missed_start")  # NaN last (no record): missed_start
        # a host clock: the stamp tells nothing about the gyro's power-on
        if 0.0 <= time_s - last <= self._gap_s or (
                0.0 <= time_s - since <= self.config.warmup_window_s):
            return "restart"
        return ""

    def on_rate(self, x: float, y: float, z: float) -> None:
        """One raw rate frame (°/s)."""
        if self._acc is None:
            return
        self._row_n += 1
        self._rx += x
        self._ry += y
        self._rz += z
        self._bn += 1
        self._bs[0] += x
        self._bs[1] += y
        self._bs[2] += z
        self._bq[0] += x * x
        self._bq[1] += y * y
        self._bq[2] += z * z
        m2 = x * x + y * y + z * z
        if m2 > self._bmax:
            self._bmax = m2

    def on_estimate(self, est: TemperatureEstimate, power_on_s: float, sensor_ok: bool,
                    receive_time_s: float = math.nan) -> None:
        """One temperature frame's estimate (before the bias is refreshed), the frame
        received at wall-clock ``receive_time_s``."""
        self.poll()
        self.record.last_time_s, self.record.last_wall_s = est.time_s, receive_time_s
        acc = self._acc
        if acc is None:
            return
        n = self._row_n
        rates = (self._rx / n, self._ry / n, self._rz / n) if n else _NAN3
        self._reset_row()
        t_on = est.time_s - power_on_s
        if not t_on <= self.config.warmup_window_s:  # NaN too
            self._close("window")
            return
        usable = sensor_ok and not (est.stale or est.rejected)
        self._rows.append((t_on, est.temperature_c, est.delta_t_c, rates) if usable
                          else (t_on, math.nan, math.nan, _NAN3))
        if math.isnan(self._block_start):
            self._block_start = t_on
        if t_on - self._block_start >= self.config.rest_window_s or len(
                self._rows) >= MAX_BLOCK_ROWS:
            if not self._judge_block():
                self._close("motion")

    def poll(self) -> None:
        """Take a finished decision (frame thread, between frames)."""
        fut = self._future
        if fut is not None and fut.done():
            self._future = None
            try:
                self._done = fut.result()
            except Exception as exc:  # a bug in the decision must not stop the daemon
                log.exception("%s: learning decision failed", self.sensor)
                self._done = _Outcome(None, error=f"internal error: {exc}")
        out, self._done = self._done, None
        if out is None:
            return
        if out.decision is not None:
            self.record.decision = out.decision.to_dict()
        if out.error:  # not adopted whatever the decision said (the file was not written)
            self.record.decision = {**(self.record.decision or {}), "adopt": False,
                                    "reasons": [out.error]}
        if out.calibration is not None:
            self.record.adopted = {"time_s": out.time_s, "calibration_id": out.calibration_id}
            self.adopted = True
            self.set_current(out.calibration, out.calibration_id)
            log.info("%s: learnt calibration adopted: %s (%s); %s", self.sensor,
                     out.calibration_id, self.learnt_path,
                     "; ".join(out.decision.reasons if out.decision else ()))
            if self.on_adopt is not None:
                self.on_adopt(out.calibration, out.calibration_id)
        elif out.error:
            log.warning("%s: learning: %s", self.sensor, out.error)
        self._save()
        self.progress = self._progress()
        if self._again:
            self._again = False
            self._submit()

    def tick(self, now_s: float) -> None:
        """Housekeeping (``now_s`` monotonic): a finished decision, a periodic save."""
        self.poll()
        if self._acc is not None and now_s - self._last_save >= SAVE_PERIOD_S:
            self._last_save = now_s
            self._save()

    # --- internals -------------------------------------------------------------------------

    def _reset_row(self) -> None:
        self._row_n = 0
        self._rx = self._ry = self._rz = 0.0

    def _reset_block(self) -> None:
        self._rows = []
        self._block_start = math.nan
        self._bn = 0
        self._bs = [0.0, 0.0, 0.0]
        self._bq = [0.0, 0.0, 0.0]
        self._bmax = 0.0

    def _judge_block(self) -> bool:
        """Feed the block's rows when it is at rest (module docstring); False: motion."""
        cfg, acc, n = self.config, self._acc, self._bn
        assert acc is not None
        rest = self._bmax <= cfg.max_rate_dps ** 2
        if rest and n >= 2:
            var = max(max(q / n - (s / n) ** 2 for s, q in zip(self._bs, self._bq,
                                                              strict=True)), 0.0)
            rest = var <= cfg.max_std_dps ** 2
        rows = self._rows
        self._reset_block()
        if not rest:
            acc.add(rows[-1][0] if rows else math.nan, math.nan, math.nan, _NAN3,
                    at_rest=False)
            return False
        for t_on, temp, dtemp, rates in rows:
            if acc.add(t_on, temp, dtemp, rates, at_rest=True):
                self._used_t = [min(self._used_t[0], t_on), max(self._used_t[1], t_on)]
        return True

    def _close(self, why: str) -> None:
        """End the warm-up in progress (``why``: window, motion, power_on, shutdown,
        clock_jump) and keep it or leave it out."""
        acc, self._acc = self._acc, None
        if acc is None:
            return
        if why in ("window", "power_on", "shutdown") and self._rows:
            self._acc = acc  # the last, partial block counts when at rest
            self._judge_block()
            self._acc = None
        self._reset_block()
        stats = acc.stats()
        rest_s = self._used_t[1] - self._used_t[0] if stats is not None else 0.0
        if why == "clock_jump":
            self._left_out("clock_jump")
        elif stats is None or not rest_s >= self.config.min_rest_s:
            self._left_out("motion" if why == "motion" else "too_short")
            log.info("%s: learning: warm-up left out (%s): %.0f s at rest after %g s, "
                     "at least %g s needed", self.sensor, why, max(rest_s, 0.0), SETTLE_S,
                     self.config.min_rest_s)
        else:
            self._use(stats, why)
        self._save()
        self.progress = self._progress()

    def _use(self, stats: WarmupStats, why: str) -> None:
        self.record.learn.add(stats)
        self._last_left_out = ""
        log.info("%s: learning: warm-up used (%s ended it): %d rows, from %.1f °C, "
                 "T %.1f…%.1f °C; %d warm-ups", self.sensor, why, stats.n, stats.start_c,
                 *stats.t_range_c, len(self.record.learn.warmups))
        if why != "shutdown":  # at shutdown the next start decides
            self._submit()

    def _left_out(self, reason: str) -> None:
        self.record.rejected[reason] = self.record.rejected.get(reason, 0) + 1
        self._last_left_out = reason

    def _save(self) -> None:
        self.record.config = self.config.to_dict()
        try:
            store.save_record(self.state_path, self.record)
        except (OSError, ValueError) as exc:  # never stops the daemon; the file stays
            log.warning("%s: cannot save the learning state to %s: %s", self.sensor,
                        self.state_path, exc)

    def _submit(self) -> None:
        if self._future is not None:
            self._again = True  # one more run when this one is taken
            return
        job = _Job(self, tuple(self.record.learn.warmups))
        if self._pool is None:
            self._done = job.run()
            self.poll()
        else:
            self._future = self._pool.submit(job.run)

    def _progress(self) -> LearnProgress:
        return progress(self.record, self.config, adopted=self.adopted,
                        collecting=self._acc is not None, last_left_out=self._last_left_out)


def progress(record: store.LearnRecord, config: LearnConfig, *, adopted: bool,
             collecting: bool = False, last_left_out: str = "") -> LearnProgress:
    """The state message's ``learn`` (and ``gyrotherm learn status``) from a record."""
    ws = record.learn.warmups
    need = max(config.min_warmups - len(ws), 0)
    span = max(w.start_c for w in ws) - min(w.start_c for w in ws) if ws else 0.0
    t_min = min((w.t_range_c[0] for w in ws), default=math.nan)
    t_max = max((w.t_range_c[1] for w in ws), default=math.nan)
    d = record.decision or {}
    cand = _largest(d.get("candidate_heldout_rms_dps"))
    cur = _largest(d.get("current_heldout_rms_dps"))
    took = record.adopted if adopted else None
    if took is not None:
        when = float(took["time_s"])
        status = (f"adopted at {_utc(when) if math.isfinite(when) else 'an unknown time'} "
                  f"({took['calibration_id']}); learning goes on")
    elif need:
        status = f"learning: need {need} more warm-up{'s' if need > 1 else ''} at rest"
    elif span < config.min_span_c:
        status = f"learning: span {span:.1f} °C < {config.min_span_c:g} °C"
    elif d.get("reasons") and d.get("warmups") == len(ws):
        status = f"learning: {d['reasons'][-1]}"
    else:  # no decision yet on these warm-ups (the worker is on it): not the last one's
        status = "learning: validating"
    if last_left_out:
        status += (f"; last power-on left out: {last_left_out} "
                   f"({record.rejected.get(last_left_out, 0)} so far)")
    return LearnProgress(collecting, math.nan if took is None else float(took["time_s"]),
                         status, len(ws), dict(record.rejected), t_min, t_max, cand, cur, need)


def _largest(per_axis: Any) -> float:
    if not isinstance(per_axis, dict) or not per_axis:
        return math.nan
    vals = [v for v in per_axis.values() if isinstance(v, int | float)]
    return float(max(vals)) if vals else math.nan


class _Job:
    """The decision and, when it adopts, the learnt calibration's file (worker thread:
    only immutable inputs, copied at submission)."""

    def __init__(self, learner: Learner, warmups: tuple[WarmupStats, ...]) -> None:
        self.warmups = warmups
        self.current, self.current_id = learner.current, learner.current_id
        self.config, self.axes = learner.config, learner.axes
        self.estimator, self.path = learner.estimator, learner.learnt_path
        self.owner = {"vehicle": learner.vehicle, "sensor": learner.sensor}
        self.device_id = learner._device[0]
        self.clock = learner._clock

    def run(self) -> _Outcome:
        cfg = self.config
        try:
            d = decide(self.warmups, self.current, self.axes, margin=cfg.margin_frac,
                       min_warmups=cfg.min_warmups, min_start_span_c=cfg.min_span_c)
        except CalibrationError as exc:
            return _Outcome(None, error=f"cannot compare with the calibration in use: {exc}")
        if not d.adopt:
            return _Outcome(d)
        now = self.clock()
        cal = learnt_calibration(self.warmups, self.axes, estimator=self.estimator, decision=d,
                                 provenance={
                                     "learnt_for": self.owner,
                                     "replaces": self.current_id or "none",
                                     "margin_frac": cfg.margin_frac,
                                     "adopted_utc": _utc(now), "adopted_time_s": now,
                                     "gyrotherm_version": __version__,
                                     **({"device_id": self.device_id} if self.device_id
                                        else {})})
        text, cid = store.calibration_text(cal)
        try:  # as the next start will read it: never adopt what would then be refused
            parse_calibration(text, source=str(self.path))
        except CalibrationError as exc:
            return _Outcome(d, error=f"the learnt calibration would be refused (nothing "
                            f"adopted): {exc}")
        try:
            store.write_atomic(self.path, text)
        except OSError as exc:
            return _Outcome(d, error=f"cannot write the learnt calibration {self.path} "
                            f"(nothing adopted, the previous file is kept): {exc}")
        return _Outcome(d, calibration=cal, calibration_id=cid, time_s=now)


__all__ = ["DEVICE_CLOCK_LIMIT_S", "FIRST_FRAME_MAX_S", "SAVE_PERIOD_S", "Learner", "progress"]
