"""Streaming latency at 2 kHz: daemon path vs a bare Zenoh publisher → subscriber, same run.

Latency = the subscriber's ``time.time()`` in its callback − the message's
``receive_time_s``, which the publisher stamped with ``time.time()`` when the
frame arrived (the daemon: right after ``recv`` returned the CAN frame; the bare
publisher: just before encoding and ``put``). Both ends run on this host, so one
wall clock serves both. The first ``--warmup-s`` of every trial is left out.

Paths, interleaved round by round (``--trials`` rounds; in each round every path
once, in this order):

* ``bare``: ``bench/zenoh_baseline.py --mode multiproc --receiver bare``: a
  publisher process puts a 108-byte rate payload at ``--rate-hz``, a subscriber
  process takes the time at the start of its raw zenoh callback (strict baseline).
* ``bare_client``: the same publisher, received by :class:`gyrotherm.client.Subscriber`
  (time taken in ``on_rate``, after decode and accounting), i.e. the same
  receiving code as the daemon path.
* ``full``: frames paced at ``--rate-hz`` onto a SocketcandServer on 127.0.0.1 →
  the daemon process (``python -m gyrotherm run --config``) → the subscriber
  process (:class:`gyrotherm.client.Subscriber`, time taken in ``on_rate``).
  Also reported: *lag* = callback − the frame's scheduled send time (adds the
  socketcand hop and python-can), and the daemon's VmRSS/VmHWM at the end.
* ``core`` (with ``--chains ... core``): the daemon core fed by an in-process source.

Per path: medians over the rounds of p50 and p99 (nearest rank, exact over each
trial's samples); the headline ratio is median daemon p99 / median bare p99, with
the per-round paired ratios alongside. Prints one JSON object on stdout, a summary
on stderr. Loopback only; zenoh sessions without scouting.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import can

from stream_throughput import (
    Chain,
    ChildChain,
    FullChain,
    JSONDict,
    build_frames,
    fit_calibration,
    log,
    machine,
    median,
    memory_kb,
    prefix_for,
    run_trial,
)

BENCH_DIR = Path(__file__).resolve().parent


def baseline_trial(a: argparse.Namespace, receiver: str) -> JSONDict:
    """One ``zenoh_baseline.py`` multiproc run; latency figures converted to µs as-is."""
    argv = [sys.executable, str(BENCH_DIR / "zenoh_baseline.py"), "--mode", "multiproc",
            "--rate-hz", str(a.rate_hz), "--duration-s", str(a.trial_s + a.warmup_s),
            "--warmup-s", str(a.warmup_s), "--receiver", receiver]  # fmt: skip
    done = subprocess.run(argv, capture_output=True, text=True, timeout=120 + 2 * a.trial_s)
    if done.returncode != 0:
        raise RuntimeError(f"zenoh_baseline.py failed ({done.returncode}): {done.stderr[-2000:]}")
    out: JSONDict = json.loads(done.stdout)
    sub = out["subscriber"]
    lat = sub["latency"]
    return {"path": "bare" if receiver == "bare" else "bare_client", "receiver": receiver,
            "sent": out["publisher"]["sent"], "received": sub["received"],
            "achieved_hz": out["publisher"]["achieved_hz"], "count": lat["count"],
            "p50_us": lat["p50_us"], "p99_us": lat["p99_us"], "max_us": lat["max_us"]}


def daemon_trial(chain: Chain, frames: list[can.Message], a: argparse.Namespace) -> JSONDict:
    n_frames = prefix_for(frames, int(a.rate_hz * (a.trial_s + a.warmup_s)))
    r = run_trial(chain, n_frames, a.rate_hz, max_lag_ms=1e9, skip=int(a.rate_hz * a.warmup_s))
    s = r["subscriber"]
    lat, lag = s["latency"], s["lag"]
    return {"path": chain.name, "sent": r["rate_frames"], "received": s["received_rate"],
            "zero_loss": r["zero_loss"], "count": lat["count"],
            "p50_us": round(lat["p50_ms"] * 1e3, 1), "p99_us": round(lat["p99_ms"] * 1e3, 1),
            "max_us": round(lat["max_ms"] * 1e3, 1),
            "lag_p50_us": round(lag["p50_ms"] * 1e3, 1),
            "lag_p99_us": round(lag["p99_ms"] * 1e3, 1),
            "cpu_pct": r["cpu"]["pct"], "others_cpu_pct": r["cpu"]["others_pct"]}  # fmt: skip


def _fmt(r: JSONDict) -> str:
    extra = f"  lag p99 {r['lag_p99_us']:.0f} µs" if "lag_p99_us" in r else ""
    return (f"  {r['path']:11s} n={r['count']:5d} rx {r['received']}/{r['sent']}  "
            f"p50 {r['p50_us']:7.1f} µs  p99 {r['p99_us']:8.1f} µs  max {r['max_us']:8.1f} µs"
            f"{extra}")  # fmt: skip


def summarise(trials: list[JSONDict], daemon_paths: list[str]) -> JSONDict:
    paths = ["bare", "bare_client", *daemon_paths]
    out: JSONDict = {}
    for p in paths:
        mine = [t for t in trials if t["path"] == p]
        out[p] = {"trials": len(mine), "p50_median_us": median([t["p50_us"] for t in mine]),
                  "p99_median_us": median([t["p99_us"] for t in mine]),
                  "p99_all_us": [t["p99_us"] for t in mine]}  # fmt: skip
        if mine and "lag_p99_us" in mine[0]:
            out[p]["lag_p99_median_us"] = median([t["lag_p99_us"] for t in mine])
            out[p]["zero_loss_all"] = all(t["zero_loss"] for t in mine)
    ratios: JSONDict = {}
    for d in daemon_paths:
        for b in ("bare", "bare_client"):
            dp, bp = out[d]["p99_median_us"], out[b]["p99_median_us"]
            if dp and bp:
                ratios[f"{d}_p99_over_{b}_p99"] = round(dp / bp, 2)
                ratios[f"{d}_p50_over_{b}_p50"] = round(
                    (out[d]["p50_median_us"] or 0) / (out[b]["p50_median_us"] or 1), 2)
            paired = [td["p99_us"] / tb["p99_us"]
                      for td, tb in zip([t for t in trials if t["path"] == d],
                                        [t for t in trials if t["path"] == b], strict=False)]
            ratios[f"{d}_p99_over_{b}_p99_per_round"] = [round(x, 2) for x in paired]
    out["ratios"] = ratios
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    p.add_argument("--rate-hz", type=float, default=2000.0, help="rate messages per second")
    p.add_argument("--trials", type=int, default=7, help="rounds (each path once per round)")
    p.add_argument("--trial-s", type=float, default=2.5, help="measured seconds per trial")
    p.add_argument("--warmup-s", type=float, default=0.5, help="left out at each trial's start")
    p.add_argument("--chains", nargs="+", default=["full"], choices=["full", "core"],
                   help="daemon paths to measure (default: full)")
    a = p.parse_args(argv)
    t_begin = time.monotonic()
    result: JSONDict = {"bench": "stream_latency", "machine": machine(),
                        "settings": {"rate_hz": a.rate_hz, "trials": a.trials,
                                     "trial_s": a.trial_s, "warmup_s": a.warmup_s,
                                     "chains": a.chains}}  # fmt: skip
    n_rate = int(a.rate_hz * (a.trial_s + a.warmup_s)) + 10
    trials: list[JSONDict] = []
    with tempfile.TemporaryDirectory(prefix="gyrotherm-bench-") as tmp:
        work = Path(tmp)
        log("latency: fitting a calibration, building frames ...")
        cal = fit_calibration(work)
        frames, rel = build_frames(n_rate)
        chains: list[Chain] = []
        try:
            for name in a.chains:
                log(f"latency: starting chain {name} ...")
                chains.append(FullChain(frames, rel, cal, work) if name == "full" else
                              ChildChain("core", "core", frames, len(frames), cal))  # fmt: skip
            for k in range(a.trials):
                for receiver in ("bare", "client"):
                    r = baseline_trial(a, receiver)
                    r["round"] = k
                    trials.append(r)
                    log(_fmt(r))
                for chain in chains:
                    r = daemon_trial(chain, frames, a)
                    r["round"] = k
                    trials.append(r)
                    log(_fmt(r))
            result["memory"] = {c.name: memory_kb(c.pids["daemon"]) for c in chains}
        finally:
            for c in chains:
                c.close()
    result["trials"] = trials
    result["summary"] = summarise(trials, a.chains)
    result["elapsed_s"] = round(time.monotonic() - t_begin, 1)
    s = result["summary"]
    for d in a.chains:
        log(f"latency: {d} p99 median {s[d]['p99_median_us']} µs vs bare "
            f"{s['bare']['p99_median_us']} µs (× {s['ratios'].get(f'{d}_p99_over_bare_p99')}),"
            f" vs bare+client {s['bare_client']['p99_median_us']} µs "
            f"(× {s['ratios'].get(f'{d}_p99_over_bare_client_p99')})")
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
