"""Vehicle state faults against a real `gyrotherm run` process (socketcand bus on
127.0.0.1, Zenoh on loopback):

* a state file that is a FIFO: the daemon starts (READY) without blocking, says why in
  one journal line, and stops on SIGTERM within STOP_BOUND_S;
* a calibration replaced by a FIFO, then SIGHUP: the reload fails in one line, the
  loop goes on (health keeps coming), SIGTERM is honoured;
* a SIGHUP storm alternating valid and invalid files: the daemon stays up, the last
  (valid) file is the one in use, every failure is counted;
* an absurd calibration at start (hysteresis 1e6 °/s) or one recorded for another IMU:
  exit 2 with one line naming the file, the effect/field and the bound.
"""

from __future__ import annotations

import json
import os
import re
import signal
import sys
from pathlib import Path

from gyrotherm.client import Subscriber
from gyrotherm.compensation import Calibration
from gyrotherm.sim import SocketcandServer
from streamkit import free_port, make_v2

sys.path.insert(0, str(Path(__file__).resolve().parent))
from faultkit import STOP_BOUND_S, WAIT_S, DaemonProc, write_config


def _config(tmp_path: Path, server: SocketcandServer, zport: int, cal: Path,
            extra: str = "") -> Path:
    cfg = write_config(tmp_path / "g.toml", bus_port=server.port, zenoh_port=zport)
    head = (f'calibration = "{cal}"\nstate_dir = "{tmp_path / "state"}"\n{extra}\n')
    cfg.write_text(head + cfg.read_text())
    (tmp_path / "state").mkdir(exist_ok=True)
    return cfg


def _stop(daemon: DaemonProc) -> str:
    try:
        elapsed = daemon.terminate()
    finally:
        daemon.kill()
    err = daemon.err.text()
    assert elapsed < STOP_BOUND_S, f"SIGTERM took {elapsed:.1f} s\n{err}"
    assert daemon.proc.returncode == 0, err
    return err


def test_a_fifo_state_file_neither_blocks_the_start_nor_sigterm(
        tmp_path: Path, stream_calibration: Calibration) -> None:
    cal = make_v2(stream_calibration).save(tmp_path / "cal.json")
    server = SocketcandServer(host="127.0.0.1", port=0).start()
    try:
        cfg = _config(tmp_path, server, free_port(), cal)
        os.mkfifo(tmp_path / "state" / "faults.imu0.effects-state.json")
        daemon = DaemonProc(cfg)
        try:
            assert daemon.err.wait_for(r"gyrotherm.daemon: up: "), daemon.err.lines
            line = daemon.err.wait_for(r"effects state ignored")
            assert line and "effects-state.json: the effects state is a FIFO" in line
            err = _stop(daemon)
        finally:
            daemon.kill()
    finally:
        server.shutdown()
    assert err.count("effects state ignored") == 1


def test_a_fifo_calibration_on_sighup_and_a_sighup_storm(
        tmp_path: Path, stream_calibration: Calibration) -> None:
    cal = tmp_path / "cal.json"
    good = stream_calibration.save(tmp_path / "good.json").read_bytes()
    v2 = make_v2(stream_calibration).save(tmp_path / "v2.json").read_bytes()
    cal.write_bytes(good)
    bad = json.loads(v2)
    bad["effects"]["x"]["hysteresis"]["amplitude_dps"] = 1e6
    server = SocketcandServer(host="127.0.0.1", port=0).start()
    zport = free_port()
    try:
        daemon = DaemonProc(_config(tmp_path, server, zport, cal))
        try:
            assert daemon.err.wait_for(r"gyrotherm.daemon: up: "), daemon.err.lines
            with Subscriber("faults", "imu0", connect=[f"tcp/127.0.0.1:{zport}"]) as sub:
                assert sub.wait_for(lambda s: s.health.received >= 1, timeout_s=WAIT_S)
                cal.unlink()
                os.mkfifo(cal)
                daemon.proc.send_signal(signal.SIGHUP)
                line = daemon.err.wait_for(r"calibration reload failed")
                assert line and "cal.json: the calibration file is a FIFO" in line
                # the loop goes on: health keeps coming after the failed reload
                n = sub.stats().health.received
                assert sub.wait_for(lambda s: s.health.received >= n + 3, timeout_s=WAIT_S)
                cal.unlink()
                # a storm: 10 SIGHUPs, each after swapping the file, ending on a valid one
                contents = [json.dumps(bad).encode(), v2, b"{", good, b"\0" * 10] * 2 + [v2]
                for k, content in enumerate(contents):
                    cal.write_bytes(content)
                    daemon.proc.send_signal(signal.SIGHUP)
                    _wait_count(daemon, k + 2)  # one reload at a time: its journal line
                m = sub.stats().health.received
                assert sub.wait_for(lambda s: s.health.received >= m + 2, timeout_s=WAIT_S)
            err = _stop(daemon)
        finally:
            daemon.kill()
    finally:
        server.shutdown()
    assert "axis 'x', effect 'hysteresis': parameter 'amplitude_dps'" in err
    assert err.count("calibration reload failed") == 1 + 6
    assert err.count("calibration reloaded") == 5
    last = [x for x in err.splitlines() if "calibration reload" in x][-1]
    assert "calibration reloaded" in last


def _wait_count(daemon: DaemonProc, want: int) -> None:
    """Wait until ``want`` reload outcomes (reloaded or failed) are in the journal."""
    rx = re.compile(r"calibration reloaded|calibration reload failed")

    def count() -> int:
        return sum(1 for x in daemon.err.lines if rx.search(x))

    with daemon.err._cond:
        daemon.err._cond.wait_for(lambda: count() >= want, WAIT_S)
        assert count() >= want, daemon.err.lines


def test_an_absurd_or_foreign_calibration_at_start_exits_2_naming_it(
        tmp_path: Path, stream_calibration: Calibration) -> None:
    doc = json.loads(make_v2(stream_calibration).save(tmp_path / "v2.json").read_text())
    doc["effects"]["y"]["warmup"]["amplitude_dps"] = 1e308
    absurd = tmp_path / "absurd.json"
    absurd.write_text(json.dumps(doc))
    foreign = stream_calibration.save(tmp_path / "foreign.json")
    d = json.loads(foreign.read_text())
    d["provenance"]["device_id"] = "2490378"
    foreign.write_text(json.dumps(d))
    server = SocketcandServer(host="127.0.0.1", port=0).start()
    try:
        for cal, extra, want in [
            (absurd, "", "absurd.json: axis 'y', effect 'warmup': parameter 'amplitude_dps' "
             "gives |bias| up to 1e+308 °/s (|A|), more than the 30 °/s bound"),
            (foreign, 'device_id = "2490379"', "foreign.json: field 'provenance.device_id' = "
             "'2490378' is not this sensor's device_id = '2490379'"),
        ]:
            daemon = DaemonProc(_config(tmp_path, server, free_port(), cal, extra))
            try:
                daemon.proc.wait(WAIT_S)
            finally:
                daemon.kill()
            err = daemon.err.text()
            assert daemon.proc.returncode == 2, err
            assert want in err and "Traceback" not in err
    finally:
        server.shutdown()
