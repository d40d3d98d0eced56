"""Daemon config files: valid examples load, bad ones name the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from gyrotherm import ConfigError
from gyrotherm.daemon import load_config, parse_config

REPO = Path(__file__).resolve().parents[2]


def test_full_example(tmp_path: Path) -> None:
    cfg_file = tmp_path / "g.toml"
    cfg_file.write_text("""
vehicle = "veh01"
sensor = "imu0"
calibration = "cal.json"
health_period_s = 0.5
[can]
interface = "socketcand"
host = "127.0.0.1"
port = 29536
channel = "vcan0"
on_counter_jump = "reject"
[can.signals]
rate_message = "GyroRate"
rate_x_signal = "RateX"
rate_y_signal = "RateY"
rate_z_signal = "RateZ"
temperature_message = "GyroTemperature"
temperature_signal = "Temperature"
[estimator]
stale_after_s = 2.0
[zenoh]
listen = ["tcp/127.0.0.1:7500"]
""")
    cfg = load_config(cfg_file)
    assert cfg.calibration == tmp_path / "cal.json"
    assert cfg.can.port == 29536 and cfg.can.on_counter_jump == "reject"
    assert cfg.can.signals.rate_crc_signal is None
    assert cfg.estimator.stale_after_s == 2.0
    assert cfg.zenoh.listen == ("tcp/127.0.0.1:7500",)


@pytest.mark.parametrize("name", ["gyrotherm.toml", "gyrotherm-bench-socketcand.toml",
                                  "gyrotherm-bench-vcan0.toml"])
def test_shipped_configs_load(name: str) -> None:
    cfg = load_config(REPO / "deploy" / "config" / name)
    assert cfg.vehicle and cfg.sensor


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        ('sensor = "a"', "keys 'vehicle' and 'sensor' are required"),
        ('vehicle = "v/1"\nsensor = "a"', "vehicle name 'v/1' is invalid"),
        ('vehicle = "v"\nsensor = "a"\ncolour = 1', r"unknown key\(s\) \['colour'\]"),
        ('vehicle = "v"\nsensor = "a"\n[can]\ninterface = "usb"', "interface 'usb' is not one"),
        ('vehicle = "v"\nsensor = "a"\n[can]\nbitrate = 5', "bitrate = 5 is outside"),
        ('vehicle = "v"\nsensor = "a"\n[can]\nbitrate = "fast"', "key 'bitrate' must be int"),
        ('vehicle = "v"\nsensor = "a"\n[can]\ninterface = "socketcand"',
         "'socketcand' needs 'host' and 'port'"),
        ('vehicle = "v"\nsensor = "a"\n[can.signals]\nrate_message = "X"',
         r"\[can\]\.signals: missing key\(s\) \['rate_x_signal', 'rate_y_signal'"),
        ('vehicle = "v"\nsensor = "a"\n[estimator]\ntau_s = "x"',
         r"\[estimator\]: estimator.tau_s: expected a number, got 'x'"),
        ('vehicle = "v"\nsensor = "a"\nhealth_period_s = 0', "health_period_s = 0 is outside"),
        ('vehicle = "v"\nsensor = "a"\n[zenoh]\nconfig = "z.json5"\nmode = "peer"',
         "'config' excludes"),
        ('vehicle = "v"\nsensor = "a"\n[estimator]\ntau_s = -1', r"estimator.tau_s = -1"),
        ('vehicle = "v"\nsensor = "a"\n[zenoh]\nmode = "bogus"', "mode 'bogus' is not"),
        ('vehicle = "v"\nsensor = "a"\n[zenoh]\nmode = "client"',
         r"\[zenoh\]: zenoh client mode needs at least one connect endpoint"),
        ('vehicle = "v"\nsensor = "a"\n[zenoh]\nlisten = ["tcp/0.0.0.0:7447"]',
         "listens on all interfaces"),
        ('vehicle = "v"\nsensor = "a"\n[zenoh]\ncongestion_control = "drop"',
         r"unknown key\(s\) \['congestion_control'\]"),
        ('vehicle = "v"\nsensor = "a"\n[can]\ninterface = "virtual"\nhost = "h"',
         "apply only to interface 'socketcand'"),
        ('vehicle = "v"\nsensor = "a"\n[can]\nbitrate = 2000000', "bitrate = 2000000"),
        ('vehicle = "v"\nsensor = "a"\n[can]\nstart_timeout_s = 0',
         r"\[can\]: start_timeout_s = 0 is outside \[0.5, 600\]"),
        ('vehicle = "v"\nsensor = "a"\n[can]\nstart_timeout_s = "soon"',
         "key 'start_timeout_s' must be int or float, got 'soon'"),
        ('vehicle = "v"\nsensor = "a"\n[zenoh]\npublish_block_max_s = 5',
         r"\[zenoh\]: publish_block_max_s = 5 is outside \[0.01, 2\]"),
        ('vehicle = "v"\nsensor = "a"\n[zenoh]\npublish_block_max_s = nan',
         r"publish_block_max_s = nan is outside"),
    ],
)
def test_bad_configs_name_the_key(tmp_path: Path, toml: str, message: str) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(toml)
    with pytest.raises(ConfigError, match=message) as info:
        load_config(p)
    assert str(info.value).startswith(f"{p}: "), "the error names the file first"


def test_not_toml_and_missing(tmp_path: Path) -> None:
    p = tmp_path / "bad.toml"
    p.write_text("vehicle = ")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(p)
    with pytest.raises(ConfigError, match="cannot read config file"):
        load_config(tmp_path / "absent.toml")
    with pytest.raises(ConfigError, match="must be a table"):
        parse_config({"vehicle": "v", "sensor": "s", "can": 3})


def test_client_mode_listens_nowhere_by_default() -> None:
    cfg = parse_config({"vehicle": "v", "sensor": "s",
                        "zenoh": {"mode": "client", "connect": ["tcp/127.0.0.1:7447"]}})
    assert cfg.zenoh.listen == ()


def test_start_and_publish_bounds_defaults_and_zenoh_setting() -> None:
    from gyrotherm._zenoh import session_config
    from gyrotherm.daemon._sink import bound_publishing

    cfg = parse_config({"vehicle": "v", "sensor": "a"})
    assert cfg.can.start_timeout_s == 20.0  # fits the unit's TimeoutStartSec=30s
    assert cfg.zenoh.publish_block_max_s == 0.5  # well under WatchdogSec/2 = 2.5 s
    cfg = parse_config({"vehicle": "v", "sensor": "a", "can": {"start_timeout_s": 3},
                        "zenoh": {"publish_block_max_s": 0.25}})
    assert (cfg.can.start_timeout_s, cfg.zenoh.publish_block_max_s) == (3.0, 0.25)
    zconf = session_config(mode="peer", listen=[], connect=[])
    bound_publishing(zconf, 0.25)
    block = "transport/link/tx/queue/congestion_control/block/wait_before_close"
    assert zconf.get_json(block) == "250000"  # µs
    assert zconf.get_json("transport/link/tcp/so_sndbuf") == "131072"
    zconf.insert_json5("transport/link/tcp/so_sndbuf", "65536")  # a file's own value stays
    bound_publishing(zconf, 0.25)
    assert zconf.get_json("transport/link/tcp/so_sndbuf") == "65536"
