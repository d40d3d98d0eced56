//! Servo-loop example: damp the yaw rate with the daemon's thermally corrected gyro rate
//! (the Rust twin of examples/servo_loop.py).
//!
//!     cargo run --example servo_loop -- --vehicle rover1 --sensor imu0 \
//!         --connect tcp/127.0.0.1:7447 --max-samples 1000 --timeout-s 2
//!
//! Each rate message gives one command `command_dps = -gain · rate_dps[z]` (°/s).
//! The loop stops after `--max-samples` messages, or when none arrives for
//! `--timeout-s` seconds (a watchdog: exit status 1 then). `--json` prints one JSON
//! object per line: `{"event":"ready","calibration_id":…}` once the daemon's first
//! health message arrived (the subscription is in place) and its calibration
//! queryable answered (`null` if it did not), one `"sample"` per rate message, then
//! `"done"` with the rate stream's statistics (gaps, latency p50/p99/max in ms).

use std::process::ExitCode;
use std::time::Duration;

use gyrotherm_client::{StreamStats, Subscriber};

struct Args {
    vehicle: String,
    sensor: String,
    connect: Vec<String>,
    gain: f64,
    max_samples: u64,
    timeout_s: f64,
    ready_timeout_s: f64,
    json: bool,
}

const USAGE: &str = "usage: servo_loop [--vehicle V] [--sensor S] [--connect ENDPOINT]... \
[--gain G] [--max-samples N] [--timeout-s T] [--ready-timeout-s T] [--json]";

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        vehicle: "rover1".into(),
        sensor: "imu0".into(),
        connect: Vec::new(),
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
    if a.connect.is_empty() {
        a.connect
            .push(gyrotherm_client::subscriber::DEFAULT_CONNECT.into());
    }
    Ok(a)
}

/// JSON number (shortest round-trip form); NaN/inf as null.
fn num(v: f64) -> String {
    if v.is_finite() {
        format!("{v:?}")
    } else {
        "null".into()
    }
}

fn ms(v_s: f64) -> String {
    num(v_s * 1e3)
}

fn stats_json(s: &StreamStats) -> String {
    let l = &s.latency;
    format!(
        "{{\"received\":{},\"gaps\":{},\"missing\":{},\"resets\":{},\"duplicates\":{},\
         \"undecodable\":{},\"dropped\":{},\"non_finite\":{},\"latency_count\":{},\
         \"latency_mean_ms\":{},\"latency_p50_ms\":{},\"latency_p99_ms\":{},\"latency_max_ms\":{}}}",
        s.received, s.gaps, s.missing, s.resets, s.duplicates, s.undecodable, s.dropped,
        s.non_finite, l.count, ms(l.mean_s), ms(l.p50_s), ms(l.p99_s), ms(l.max_s)
    )
}

fn main() -> ExitCode {
    let a = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("servo_loop: {e}");
            return ExitCode::from(2);
        }
    };
    let sub = match Subscriber::connect(&a.vehicle, &a.sensor, &a.connect, 1024) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("servo_loop: {e}");
            return ExitCode::from(2);
        }
    };
    if a.json {
        // the daemon publishes health every health_period_s: once one arrived, the
        // route to this subscriber exists and no rate message will be missed
        let ready_timeout = Duration::from_secs_f64(a.ready_timeout_s);
        if !sub.wait_for(|s| s.health.received >= 1, ready_timeout) {
            eprintln!(
                "servo_loop: no health message on {} within {} s (daemon at {:?}?)",
                sub.keys().health,
                a.ready_timeout_s,
                a.connect
            );
            return ExitCode::from(1);
        }
        // the daemon's calibration queryable: which calibration compensates these rates
        let calibration_id = match sub.query_calibration(Duration::from_secs(5)) {
            Ok(info) => format!("{:?}", info.calibration_id),
            Err(e) => {
                eprintln!("servo_loop: {e}");
                "null".into()
            }
        };
        println!("{{\"event\":\"ready\",\"calibration_id\":{calibration_id}}}");
    }

    // ---- the servo loop itself ------------------------------------------------
    let mut n = 0u64;
    if a.max_samples > 0 {
        for msg in sub.rates(Duration::from_secs_f64(a.timeout_s)) {
            let command_dps = -a.gain * msg.rate_dps[2]; // yaw-rate damping
            if a.json {
                println!(
                    "{{\"event\":\"sample\",\"seq\":{},\"sensor_time_s\":{},\"receive_time_s\":{},\
                     \"rate_dps\":[{},{},{}],\"raw_rate_dps\":[{},{},{}],\"bias_dps\":[{},{},{}],\
                     \"flags\":{},\"command_dps\":{}}}",
                    msg.seq,
                    num(msg.sensor_time_s),
                    num(msg.receive_time_s),
                    num(msg.rate_dps[0]),
                    num(msg.rate_dps[1]),
                    num(msg.rate_dps[2]),
                    num(msg.raw_rate_dps[0]),
                    num(msg.raw_rate_dps[1]),
                    num(msg.raw_rate_dps[2]),
                    num(msg.bias_dps[0]),
                    num(msg.bias_dps[1]),
                    num(msg.bias_dps[2]),
                    msg.flags,
                    num(command_dps)
                );
            } else {
                println!(
                    "seq={} yaw_dps={:.6} command_dps={command_dps:.6} flags={}",
                    msg.seq, msg.rate_dps[2], msg.flags
                );
            }
            n += 1;
            if n >= a.max_samples {
                break;
            }
        }
    }
    let stats = sub.stats().rate;
    if a.json {
        println!(
            "{{\"event\":\"done\",\"samples\":{n},\"rate\":{}}}",
            stats_json(&stats)
        );
    } else {
        let l = &stats.latency;
        println!(
            "done: {n} samples, {} gaps, latency p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
            stats.gaps,
            l.p50_s * 1e3,
            l.p99_s * 1e3,
            l.max_s * 1e3
        );
    }
    if n >= a.max_samples {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}
