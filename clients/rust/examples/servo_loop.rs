//! Servo-loop example: damp the yaw rate with the daemon's thermally corrected gyro rate
//! (the Rust twin of examples/servo_loop.py).
//!
//!     cargo run --example servo_loop -- --vehicle rover1 --sensor imu0 \
//!         --connect tcp/127.0.0.1:7447 --max-samples 1000 --timeout-s 2
//!
//! or, through a router with a login or mutual TLS, with a Zenoh configuration file
//! instead of `--connect` (as `gyrotherm listen --zenoh-config`):
//!
//!     cargo run --example servo_loop -- --vehicle rover1 --sensor imu0 \
//!         --zenoh-config viewer.json5
//!
//! Only a clean sample gives a command `command_dps = -gain · rate_dps[z]` (°/s).
//! Clean means `flags == 0`, the Python client's notion (docs/wire-format.md,
//! "Status flags": a loop testing `if sample.flags:` never takes a flagged sample for
//! clean): a sample with any flag set — NON_FINITE (a NaN or ±inf value),
//! BIAS_INVALID (the raw rate, uncompensated), TEMPERATURE_STALE, T_CLAMPED,
//! ESTIMATOR_WARMUP (after a daemon start), ZERO_PENDING, …, or a bit this version
//! does not know — is skipped: no command, counted per flag. A real loop would hold
//! or zero its command meanwhile; which flags it can live with is its own decision.
//!
//! The loop stops after `--max-samples` rate messages (used or skipped), or when none
//! arrives for `--timeout-s` seconds (a watchdog: exit status 1 then). A session that
//! cannot open (router unreachable, login or certificate refused) exits with status
//! 2 and the reason on stderr.
//!
//! `--json` prints one JSON object per line (RFC 8259: a NaN or ±inf value is
//! `null`): `{"event":"ready","calibration_id":…}` once the daemon's first health
//! message arrived (the subscription is in place) and its calibration queryable
//! answered (`null` if it did not); per rate message a `"sample"` with its
//! `command_dps`, or a `"skipped"` with the flag names; then `"done"` with the counts
//! (`samples`, `commands`, `skipped`, `skipped_by_flag`) and the rate stream's
//! statistics (gaps, latency p50/p99/max in ms).

use std::collections::BTreeMap;
use std::process::ExitCode;
use std::time::Duration;

use gyrotherm_client::decode::flags;
use gyrotherm_client::{RateMessage, StreamStats, Subscriber};
use serde_json::{json, Value};

struct Args {
    vehicle: String,
    sensor: String,
    connect: Vec<String>,
    zenoh_config: Option<String>,
    gain: f64,
    max_samples: u64,
    timeout_s: f64,
    ready_timeout_s: f64,
    json: bool,
}

const USAGE: &str = "usage: servo_loop [--vehicle V] [--sensor S] \
[--connect ENDPOINT]... | [--zenoh-config JSON5] \
[--gain G] [--max-samples N] [--timeout-s T] [--ready-timeout-s T] [--json]";

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        vehicle: "rover1".into(),
        sensor: "imu0".into(),
        connect: Vec::new(),
        zenoh_config: None,
        gain: 2.0,
        max_samples: 1000,
        timeout_s: 2.0,
        ready_timeout_s: 30.0,
        json: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        if flag == "--json" {
            a.json = true;
            continue;
        }
        if flag == "-h" || flag == "--help" {
            return Err(USAGE.into());
        }
        let value = it
            .next()
            .ok_or_else(|| format!("{flag}: missing value\n{USAGE}"))?;
        let num = |what: &str| -> Result<f64, String> {
            value
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("{what} = {value:?} is not a finite number"))
        };
        match flag.as_str() {
            "--vehicle" => a.vehicle = value,
            "--sensor" => a.sensor = value,
            "--connect" => a.connect.push(value),
            "--zenoh-config" => a.zenoh_config = Some(value),
            "--gain" => a.gain = num("--gain")?,
            "--max-samples" => {
                a.max_samples = value
                    .parse()
                    .map_err(|_| format!("--max-samples = {value:?} is not a count"))?
            }
            "--timeout-s" => a.timeout_s = num("--timeout-s")?.max(0.0),
            "--ready-timeout-s" => a.ready_timeout_s = num("--ready-timeout-s")?.max(0.0),
            other => return Err(format!("unknown option {other}\n{USAGE}")),
        }
    }
    if a.zenoh_config.is_some() && !a.connect.is_empty() {
        return Err(
            "--connect and --zenoh-config exclude each other: put the endpoints \
                    in the file"
                .into(),
        );
    }
    if a.connect.is_empty() && a.zenoh_config.is_none() {
        a.connect
            .push(gyrotherm_client::subscriber::DEFAULT_CONNECT.into());
    }
    Ok(a)
}

/// A JSON number (shortest round-trip form), `null` for NaN or ±inf.
fn num(v: f64) -> Value {
    serde_json::Number::from_f64(v).map_or(Value::Null, Value::Number)
}

fn ms(v_s: f64) -> Value {
    num(v_s * 1e3)
}

fn stats_json(s: &StreamStats) -> Value {
    let l = &s.latency;
    json!({
        "received": s.received, "gaps": s.gaps, "missing": s.missing, "resets": s.resets,
        "duplicates": s.duplicates, "undecodable": s.undecodable, "dropped": s.dropped,
        "non_finite": s.non_finite, "latency_count": l.count,
        "latency_mean_ms": ms(l.mean_s), "latency_p50_ms": ms(l.p50_s),
        "latency_p99_ms": ms(l.p99_s), "latency_max_ms": ms(l.max_s),
    })
}

fn sample_json(event: &str, msg: &RateMessage) -> serde_json::Map<String, Value> {
    let v3 = |v: &[f64; 3]| Value::Array(v.iter().map(|x| num(*x)).collect());
    let Value::Object(map) = json!({
        "event": event, "seq": msg.seq, "sensor_time_s": num(msg.sensor_time_s),
        "receive_time_s": num(msg.receive_time_s), "rate_dps": v3(&msg.rate_dps),
        "raw_rate_dps": v3(&msg.raw_rate_dps), "bias_dps": v3(&msg.bias_dps),
        "flags": msg.flags,
    }) else {
        unreachable!("json! of an object literal is an object")
    };
    map
}

fn open(a: &Args) -> Result<Subscriber, gyrotherm_client::Error> {
    match &a.zenoh_config {
        Some(file) => Subscriber::from_config_file(&a.vehicle, &a.sensor, file, 1024),
        None => Subscriber::connect(&a.vehicle, &a.sensor, &a.connect, 1024),
    }
}

fn main() -> ExitCode {
    let a = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("servo_loop: {e}");
            return ExitCode::from(2);
        }
    };
    let sub = match open(&a) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("servo_loop: {e}");
            return ExitCode::from(2);
        }
    };
    let via = match &a.zenoh_config {
        Some(file) => format!("zenoh config {file}"),
        None => format!("{:?}", a.connect),
    };
    if a.json {
        // the daemon publishes health every health_period_s: once one arrived, the
        // route to this subscriber exists and no rate message will be missed
        let ready_timeout = Duration::from_secs_f64(a.ready_timeout_s);
        if !sub.wait_for(|s| s.health.received >= 1, ready_timeout) {
            eprintln!(
                "servo_loop: no health message on {} within {} s (daemon reachable via {via}?)",
                sub.keys().health,
                a.ready_timeout_s,
            );
            return ExitCode::from(1);
        }
        // the daemon's calibration queryable: which calibration compensates these rates
        let calibration_id = match sub.query_calibration(Duration::from_secs(5)) {
            Ok(info) => Value::String(info.calibration_id),
            Err(e) => {
                eprintln!("servo_loop: {e}");
                Value::Null
            }
        };
        println!(
            "{}",
            json!({"event": "ready", "calibration_id": calibration_id})
        );
    }

    // ---- the servo loop itself ------------------------------------------------
    let (mut n, mut commands) = (0u64, 0u64);
    let mut skipped_by_flag = BTreeMap::<String, u64>::new();
    if a.max_samples > 0 {
        for msg in sub.rates(Duration::from_secs_f64(a.timeout_s)) {
            n += 1;
            if msg.flags == 0 {
                let command_dps = -a.gain * msg.rate_dps[2]; // yaw-rate damping
                commands += 1;
                if a.json {
                    let mut out = sample_json("sample", &msg);
                    out.insert("command_dps".into(), num(command_dps));
                    println!("{}", Value::Object(out));
                } else {
                    println!(
                        "seq={} yaw_dps={:.6} command_dps={command_dps:.6}",
                        msg.seq, msg.rate_dps[2]
                    );
                }
            } else {
                // not clean: no command from this sample
                let names = flags::names(msg.flags);
                for name in &names {
                    *skipped_by_flag.entry(name.clone()).or_default() += 1;
                }
                if a.json {
                    let mut out = sample_json("skipped", &msg);
                    out.insert("flag_names".into(), json!(names));
                    println!("{}", Value::Object(out));
                } else {
                    println!(
                        "seq={} skipped: flags={:#x} ({})",
                        msg.seq,
                        msg.flags,
                        names.join("|")
                    );
                }
            }
            if n >= a.max_samples {
                break;
            }
        }
    }
    let stats = sub.stats().rate;
    let skipped = n - commands;
    if a.json {
        println!(
            "{}",
            json!({
                "event": "done", "samples": n, "commands": commands, "skipped": skipped,
                "skipped_by_flag": skipped_by_flag, "rate": stats_json(&stats),
            })
        );
    } else {
        let l = &stats.latency;
        println!(
            "done: {n} samples, {commands} commands, {skipped} skipped, {} gaps, \
             latency p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
            stats.gaps,
            l.p50_s * 1e3,
            l.p99_s * 1e3,
            l.max_s * 1e3
        );
    }
    if n >= a.max_samples {
        ExitCode::SUCCESS
    } else {
        eprintln!(
            "servo_loop: no rate message on {} for {} s (watchdog) after {n} of {}",
            sub.keys().rate,
            a.timeout_s,
            a.max_samples
        );
        ExitCode::from(1)
    }
}
