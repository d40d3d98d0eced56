"""`gyrotherm listen` with no daemon: says what it waits for, then gives up with a hint."""

from __future__ import annotations

import subprocess
import sys

from gyrotherm.client._listen import NOTHING_TIMEOUT_S
from streamkit import dead_port


def test_listen_says_what_it_waits_for_and_gives_up() -> None:
    with dead_port() as port:
        endpoint = f"tcp/127.0.0.1:{port}"
        done = subprocess.run(
            [sys.executable, "-m", "gyrotherm", "listen", "--vehicle", "nobody", "--sensor",
             "imu0", "--connect", endpoint, "--count", "5", "--timeout-s", "1"],
            capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done
    err = done.stderr
    assert f"waiting for gyrotherm/nobody/imu0/{{rate,state,health}} via {endpoint}" in err
    assert "nothing from gyrotherm/nobody/imu0 in 1 s" in err
    assert "gyrotherm run" in err and "--timeout-s" in err and "--connect" in err
    assert "rate: received=0" in done.stdout


def test_default_give_up_time_is_documented() -> None:
    help_text = subprocess.run([sys.executable, "-m", "gyrotherm", "listen", "--help"],
                               capture_output=True, text=True, timeout=60).stdout
    assert f"{NOTHING_TIMEOUT_S:g} s when nothing" in " ".join(help_text.split())
