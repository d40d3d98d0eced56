//! Subscriber to a gyrotherm daemon over Eclipse Zenoh.
//!
//! One zenoh subscriber on `gyrotherm/<vehicle>/<sensor>/*` (as the Python
//! `Subscriber`): each sample on the rate, state or health key is decoded in zenoh's
//! callback thread ([`crate::decode`]) and accounted per stream (sequence gaps,
//! latency = wall clock at arrival − `receive_time_s`). Rate messages are queued
//! (bounded, oldest dropped first and counted) for [`Subscriber::recv_rate`]; the
//! latest state and health are kept. Undecodable payloads are counted with their
//! error, never raised into zenoh.
//!
//! The session comes from one of three places, as in the Python client:
//! * [`Subscriber::connect`]: endpoints only, with the Python client's safe defaults
//!   ([`session_config`]: a peer that listens nowhere, no scouting);
//! * [`Subscriber::from_config_file`]: a Zenoh JSON5 configuration file, loaded
//!   unchanged as by `gyrotherm listen --zenoh-config` and
//!   `open_session(config_file=...)` ([`session_config_file`]): router login
//!   (`transport/auth/usrpwd`, deploy/zenoh/client-of-router.json5) and mutual TLS
//!   (deploy/zenoh/tls-mutual.json5) are set there;
//! * [`Subscriber::with_config`]: a [`zenoh::Config`] built by the caller.

use std::collections::VecDeque;
use std::fmt;
use std::path::Path;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use zenoh::sample::{Sample, SampleKind};
use zenoh::{Config, Session, Wait};

use crate::decode::{
    decode_calibration_info, decode_health, decode_rate, decode_state, flags, CalibrationInfo,
    DecodeError, HealthMessage, RateMessage, StateMessage,
};
use crate::stats::{LatencyTracker, SequenceTracker, StreamStats};

/// The Python client's default endpoint.
pub const DEFAULT_CONNECT: &str = "tcp/127.0.0.1:7447";

/// Errors of the subscriber (configuration, zenoh, the calibration query).
#[derive(Debug)]
pub enum Error {
    /// A bad vehicle/sensor name or endpoint; the text says which and why.
    Config(String),
    /// Zenoh failed (open, declare, get).
    Zenoh(String),
    /// The calibration reply did not decode.
    Decode(crate::decode::DecodeError),
    /// The calibration queryable answered with an error.
    Calibration(String),
    /// No reply within the timeout.
    Timeout(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Config(s) | Error::Zenoh(s) | Error::Calibration(s) | Error::Timeout(s) => {
                f.write_str(s)
            }
            Error::Decode(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for Error {}

/// The four key expressions of one gyro.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Keys {
    pub rate: String,
    pub state: String,
    pub health: String,
    pub calibration: String,
}

fn check_name(what: &str, name: &str) -> Result<(), Error> {
    let ok_chars = name
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '-'));
    let len = name.chars().count();
    if !(1..=64).contains(&len) || !ok_chars || name.starts_with(['.', '-']) {
        return Err(Error::Config(format!(
            "{what} name {name:?} is invalid: expected 1-64 characters of [A-Za-z0-9_.-], \
             not starting with '.' or '-'"
        )));
    }
    Ok(())
}

/// `gyrotherm/<vehicle>/<sensor>/{rate,state,health,calibration}`; names are checked
/// as by the Python `gyrotherm._zenoh.keys`.
pub fn keys(vehicle: &str, sensor: &str) -> Result<Keys, Error> {
    check_name("vehicle", vehicle)?;
    check_name("sensor", sensor)?;
    let p = format!("gyrotherm/{vehicle}/{sensor}");
    Ok(Keys {
        rate: format!("{p}/rate"),
        state: format!("{p}/state"),
        health: format!("{p}/health"),
        calibration: format!("{p}/calibration"),
    })
}

/// The password shipped in deploy/zenoh/client-of-router.json5; a configuration file
/// still holding it is refused (as by the Python client and the daemon).
pub const PLACEHOLDER_PASSWORD: &str = "REPLACE-WITH-A-SECRET";

/// A zenoh error's text without the Rust source locations zenoh appends
/// (`… at /root/.cargo/…/config.rs:86.`), as the Python `zenoh_error_text`.
pub fn zenoh_error_text(error: &dyn fmt::Display) -> String {
    let text = error.to_string();
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(i) = rest.find(" at ") {
        let after = &rest[i + 4..];
        let token_end = after.find(char::is_whitespace).unwrap_or(after.len());
        let token = after[..token_end].trim_end_matches('.');
        let is_location = token.rsplit_once(".rs:").is_some_and(|(_, line)| {
            !line.is_empty() && line.chars().all(|c| c.is_ascii_digit() || c == ':')
        });
        if is_location {
            out.push_str(&rest[..i]);
            rest = &after[token_end..];
        } else {
            out.push_str(&rest[..i + 4]);
            rest = after;
        }
    }
    out.push_str(rest);
    let out = plain_json5_message(&out);
    let out = out.trim().trim_end_matches('.').trim();
    out.to_string()
}

/// `Message { msg: "unknown variant …", location: Some(Location { line: 1, column: 9 }) }`
/// (json5's Debug form in zenoh's config errors) → `unknown variant … (line 1, column 9)`.
fn plain_json5_message(text: &str) -> String {
    const HEAD: &str = "Message { msg: \"";
    let Some(start) = text.find(HEAD) else {
        return text.to_string();
    };
    let body = &text[start + HEAD.len()..];
    let (mut msg, mut escaped, mut end) = (String::new(), false, None);
    for (i, c) in body.char_indices() {
        match (escaped, c) {
            (true, c) => {
                msg.push(c);
                escaped = false;
            }
            (false, '\\') => escaped = true,
            (false, '"') => {
                end = Some(i + 1);
                break;
            }
            (false, c) => msg.push(c),
        }
    }
    let Some(end) = end else {
        return text.to_string();
    };
    let tail = &body[end..];
    let number_after = |key: &str| -> Option<String> {
        let at = tail.find(key)? + key.len();
        let digits: String = tail[at..]
            .chars()
            .take_while(char::is_ascii_digit)
            .collect();
        (!digits.is_empty()).then_some(digits)
    };
    let (located, close) = if tail.starts_with(", location: Some(Location {") {
        (
            number_after("line: ")
                .zip(number_after("column: "))
                .map(|(l, c)| format!("{msg} (line {l}, column {c})")),
            "}) }",
        )
    } else if tail.starts_with(", location: None }") {
        (Some(msg), " }")
    } else {
        (None, "")
    };
    match (located, tail.find(close)) {
        (Some(plain), Some(at)) => {
            format!("{}{plain}{}", &text[..start], &tail[at + close.len()..])
        }
        _ => text.to_string(),
    }
}

/// The zenoh links compiled in (Cargo.toml features `transport_tcp`, `transport_tls`).
const LINKS: [&str; 2] = ["tcp", "tls"];

/// The double-quoted strings of a JSON text (zenoh's `get_json` of an endpoint list:
/// endpoints and, for a mode-dependent list, mode names).
fn quoted(json: &str) -> impl Iterator<Item = &str> {
    json.split('"').skip(1).step_by(2)
}

/// A Zenoh configuration file (JSON5) loaded unchanged, as the Python
/// `session_config(config_file=...)`: zenoh checks its keys and values; a
/// `transport/auth/usrpwd/password` still equal to [`PLACEHOLDER_PASSWORD`] is
/// refused, and so is an endpoint of a link this crate does not compile (only `tcp/`
/// and `tls/`; zenoh would say "Unable to connect"). Errors name the file.
pub fn session_config_file(config_file: impl AsRef<Path>) -> Result<Config, Error> {
    let path = config_file.as_ref();
    let source = format!("zenoh config file {:?}", path.display().to_string());
    let config = Config::from_file(path)
        .map_err(|e| Error::Config(format!("{source}: {}", zenoh_error_text(&e))))?;
    for key in ["connect/endpoints", "listen/endpoints"] {
        let endpoints = config.get_json(key).unwrap_or_default();
        let other_link = quoted(&endpoints).find(|e| {
            e.split_once('/')
                .is_some_and(|(proto, _)| !LINKS.contains(&proto))
        });
        if let Some(endpoint) = other_link {
            return Err(Error::Config(format!(
                "{source}: {key} {endpoint:?}: this build of gyrotherm-client has the {} \
                 links only (zenoh features in clients/rust/Cargo.toml)",
                LINKS.join(" and ")
            )));
        }
    }
    if let Ok(password) = config.get_json("transport/auth/usrpwd/password") {
        if password == format!("{PLACEHOLDER_PASSWORD:?}") {
            return Err(Error::Config(format!(
                "{source}: transport/auth/usrpwd/password is still the shipped placeholder \
                 {PLACEHOLDER_PASSWORD:?}: set the password the router's dictionary file has \
                 for this user (docs/operations.md, \"Threat model\")"
            )));
        }
    }
    Ok(config)
}

/// The Python client's session defaults: a peer that listens nowhere, connects to
/// exactly `connect`, no multicast or gossip scouting.
pub fn session_config(connect: &[String]) -> Result<Config, Error> {
    if connect.is_empty() {
        return Err(Error::Config(
            "connect: at least one endpoint needed, e.g. tcp/127.0.0.1:7447".into(),
        ));
    }
    let mut config = Config::default();
    let endpoints = format!(
        "[{}]",
        connect
            .iter()
            .map(|e| format!("{e:?}"))
            .collect::<Vec<_>>()
            .join(",")
    );
    for (key, value) in [
        ("mode", "\"peer\""),
        ("scouting/multicast/enabled", "false"),
        ("scouting/gossip/enabled", "false"),
        ("listen/endpoints", "[]"),
        ("connect/endpoints", endpoints.as_str()),
    ] {
        config
            .insert_json5(key, value)
            .map_err(|e| Error::Config(format!("zenoh config {key} = {value}: {e}")))?;
    }
    Ok(config)
}

/// Accounting of one stream (rate, state or health).
#[derive(Debug, Default)]
struct Counters {
    seq: SequenceTracker,
    latency: LatencyTracker,
    received: u64,
    undecodable: u64,
    dropped: u64,
    non_finite: u64,
    last_error: Option<String>,
}

impl Counters {
    fn observe(&mut self, seq: u64, receive_time_s: f64, arrival_s: f64) {
        self.received += 1;
        self.seq.observe(seq);
        self.latency.add(arrival_s - receive_time_s);
    }

    fn failed(&mut self, e: DecodeError) {
        self.undecodable += 1;
        self.last_error = Some(e.0);
    }

    fn snapshot(&self) -> StreamStats {
        StreamStats {
            received: self.received,
            gaps: self.seq.gaps,
            missing: self.seq.missing,
            resets: self.seq.resets,
            duplicates: self.seq.duplicates,
            undecodable: self.undecodable,
            dropped: self.dropped,
            last_seq: self.seq.last_seq,
            last_error: self.last_error.clone(),
            latency: self.latency.snapshot(),
            non_finite: self.non_finite,
        }
    }
}

/// Statistics of the three streams, as the Python `SubscriberStats`.
#[derive(Debug, Clone, PartialEq)]
pub struct SubscriberStats {
    pub rate: StreamStats,
    pub state: StreamStats,
    pub health: StreamStats,
}

#[derive(Debug)]
struct Inner {
    queue: VecDeque<RateMessage>,
    capacity: usize,
    rate: Counters,
    state: Counters,
    health: Counters,
    last_state: Option<StateMessage>,
    last_health: Option<HealthMessage>,
    closed: bool,
}

type Shared = Arc<(Mutex<Inner>, Condvar)>;

fn lock(shared: &Shared) -> MutexGuard<'_, Inner> {
    // a panic while holding the lock leaves consistent counters: keep going
    shared.0.lock().unwrap_or_else(|p| p.into_inner())
}

fn now_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

fn on_sample(shared: &Shared, keys: &Keys, sample: &Sample) {
    let arrival_s = now_s();
    if sample.kind() != SampleKind::Put {
        return;
    }
    // exact keys only, as the Python client
    let key = sample.key_expr().as_str();
    let payload = sample.payload().to_bytes();
    let mut inner = lock(shared);
    if key == keys.rate {
        match decode_rate(&payload) {
            Err(e) => inner.rate.failed(e),
            Ok(msg) => {
                inner.rate.observe(msg.seq, msg.receive_time_s, arrival_s);
                if msg.flags & flags::NON_FINITE != 0 {
                    inner.rate.non_finite += 1;
                }
                if inner.queue.len() == inner.capacity {
                    inner.queue.pop_front();
                    inner.rate.dropped += 1;
                }
                inner.queue.push_back(msg);
            }
        }
    } else if key == keys.state {
        match decode_state(&payload) {
            Err(e) => inner.state.failed(e),
            Ok(msg) => {
                inner.state.observe(msg.seq, msg.receive_time_s, arrival_s);
                inner.last_state = Some(msg);
            }
        }
    } else if key == keys.health {
        match decode_health(&payload) {
            Err(e) => inner.health.failed(e),
            Ok(msg) => {
                inner.health.observe(msg.seq, msg.receive_time_s, arrival_s);
                inner.last_health = Some(msg);
            }
        }
    } else {
        return;
    }
    drop(inner);
    shared.1.notify_all();
}

fn check_args(vehicle: &str, sensor: &str, queue_size: usize) -> Result<(), Error> {
    keys(vehicle, sensor)?;
    if queue_size < 1 {
        return Err(Error::Config(format!(
            "queue_size = {queue_size} is invalid: must be >= 1"
        )));
    }
    Ok(())
}

/// Subscribes to one gyro's rate stream; see the module docs.
pub struct Subscriber {
    keys: Keys,
    shared: Shared,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    session: Session,
}

impl Subscriber {
    /// Open a peer session connected to `connect` (e.g. `["tcp/127.0.0.1:7447"]`) and
    /// subscribe to `gyrotherm/<vehicle>/<sensor>/*`. `queue_size` ≥ 1 bounds the
    /// queue (the Python default is 1024). A connect endpoint that is not up yet is
    /// retried in the background by zenoh.
    pub fn connect(
        vehicle: &str,
        sensor: &str,
        connect: &[String],
        queue_size: usize,
    ) -> Result<Self, Error> {
        check_args(vehicle, sensor, queue_size)?;
        let config = session_config(connect)?;
        Self::open(
            vehicle,
            sensor,
            config,
            queue_size,
            &format!("connect {connect:?}"),
        )
    }

    /// Open a session from a Zenoh configuration file (JSON5, loaded unchanged by
    /// [`session_config_file`]; its mode, endpoints, login and TLS files apply) and
    /// subscribe as [`Subscriber::connect`]. The Rust twin of the Python
    /// `Subscriber(vehicle, sensor, session=open_session(config_file=...))` and of
    /// `gyrotherm listen --zenoh-config`. In client mode the open fails (with
    /// [`Error::Zenoh`]) when no router accepts the session within the file's
    /// `connect/timeout_ms`: router down, wrong password, certificate refused.
    pub fn from_config_file(
        vehicle: &str,
        sensor: &str,
        config_file: impl AsRef<Path>,
        queue_size: usize,
    ) -> Result<Self, Error> {
        check_args(vehicle, sensor, queue_size)?;
        let path = config_file.as_ref();
        let config = session_config_file(path)?;
        let source = format!("config file {:?}", path.display().to_string());
        // zenoh does not say why a link failed: name what the file controls
        Self::open(vehicle, sensor, config, queue_size, &source).map_err(|e| match e {
            Error::Zenoh(text) if text.contains("Unable to connect") => Error::Zenoh(format!(
                "{text} (unreachable, or the router/peer refused this session: check the \
                 address, the login in transport/auth/usrpwd and the certificates in \
                 transport/link/tls)"
            )),
            other => other,
        })
    }

    /// Open a session from a [`zenoh::Config`] the caller built, and subscribe as
    /// [`Subscriber::connect`].
    pub fn with_config(
        vehicle: &str,
        sensor: &str,
        config: Config,
        queue_size: usize,
    ) -> Result<Self, Error> {
        check_args(vehicle, sensor, queue_size)?;
        Self::open(vehicle, sensor, config, queue_size, "given config")
    }

    fn open(
        vehicle: &str,
        sensor: &str,
        config: Config,
        queue_size: usize,
        source: &str,
    ) -> Result<Self, Error> {
        let keys = keys(vehicle, sensor)?;
        let session = zenoh::open(config).wait().map_err(|e| {
            Error::Zenoh(format!(
                "cannot open zenoh session ({source}): {}",
                zenoh_error_text(&e)
            ))
        })?;
        let shared: Shared = Arc::new((
            Mutex::new(Inner {
                queue: VecDeque::with_capacity(queue_size.min(4096)),
                capacity: queue_size,
                rate: Counters::default(),
                state: Counters::default(),
                health: Counters::default(),
                last_state: None,
                last_health: None,
                closed: false,
            }),
            Condvar::new(),
        ));
        let (cb_shared, cb_keys) = (Arc::clone(&shared), keys.clone());
        // one subscriber for the three keys, as the Python client: one callback
        // thread, so accounting follows zenoh's delivery order
        let all = format!("gyrotherm/{vehicle}/{sensor}/*");
        let subscriber = session
            .declare_subscriber(all.clone())
            .callback(move |sample| on_sample(&cb_shared, &cb_keys, &sample))
            .wait()
            .map_err(|e| {
                Error::Zenoh(format!("zenoh subscribe {all}: {}", zenoh_error_text(&e)))
            })?;
        Ok(Self {
            keys,
            shared,
            _subscriber: subscriber,
            session,
        })
    }

    /// The gyro's key expressions.
    pub fn keys(&self) -> &Keys {
        &self.keys
    }

    /// The next rate message, or `None` when none arrives within `timeout`.
    pub fn recv_rate(&self, timeout: Duration) -> Option<RateMessage> {
        let deadline = Instant::now() + timeout;
        let mut inner = lock(&self.shared);
        loop {
            if let Some(msg) = inner.queue.pop_front() {
                return Some(msg);
            }
            if inner.closed {
                return None;
            }
            let left = deadline.checked_duration_since(Instant::now())?;
            if left.is_zero() {
                return None;
            }
            inner = self
                .shared
                .1
                .wait_timeout(inner, left)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    /// Iterate over rate messages until none arrives within `timeout`.
    pub fn rates(&self, timeout: Duration) -> impl Iterator<Item = RateMessage> + '_ {
        std::iter::from_fn(move || self.recv_rate(timeout))
    }

    /// Snapshot of every stream's counters and latency.
    pub fn stats(&self) -> SubscriberStats {
        let inner = lock(&self.shared);
        SubscriberStats {
            rate: inner.rate.snapshot(),
            state: inner.state.snapshot(),
            health: inner.health.snapshot(),
        }
    }

    /// The latest state message received, if any.
    pub fn last_state(&self) -> Option<StateMessage> {
        lock(&self.shared).last_state.clone()
    }

    /// The latest health message received, if any.
    pub fn last_health(&self) -> Option<HealthMessage> {
        lock(&self.shared).last_health.clone()
    }

    /// Block until `predicate(&self.stats())` holds (re-checked after every sample)
    /// or `timeout` passes; return whether it holds.
    pub fn wait_for(
        &self,
        predicate: impl Fn(&SubscriberStats) -> bool,
        timeout: Duration,
    ) -> bool {
        let deadline = Instant::now() + timeout;
        let mut inner = lock(&self.shared);
        loop {
            let stats = SubscriberStats {
                rate: inner.rate.snapshot(),
                state: inner.state.snapshot(),
                health: inner.health.snapshot(),
            };
            if predicate(&stats) {
                return true;
            }
            let left = match deadline.checked_duration_since(Instant::now()) {
                Some(d) if !d.is_zero() && !inner.closed => d,
                _ => return false,
            };
            inner = self
                .shared
                .1
                .wait_timeout(inner, left)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    /// Ask the daemon's `…/calibration` queryable. Only a reply on exactly that key
    /// counts (as in the Python client); error replies give [`Error::Calibration`],
    /// no reply within `timeout` [`Error::Timeout`].
    pub fn query_calibration(&self, timeout: Duration) -> Result<CalibrationInfo, Error> {
        let key = &self.keys.calibration;
        let replies = self
            .session
            .get(key.as_str())
            .timeout(timeout)
            .wait()
            .map_err(|e| Error::Zenoh(format!("zenoh get {key}: {}", zenoh_error_text(&e))))?;
        let mut error = None;
        while let Ok(reply) = replies.recv() {
            match reply.result() {
                Ok(sample) if sample.key_expr().as_str() == key => {
                    return decode_calibration_info(&sample.payload().to_bytes())
                        .map_err(Error::Decode);
                }
                Ok(_) => {}
                Err(err) => {
                    error = Some(String::from_utf8_lossy(&err.payload().to_bytes()).into_owned())
                }
            }
        }
        match error {
            Some(e) => Err(Error::Calibration(format!(
                "{key}: daemon replied with error: {e}"
            ))),
            None => Err(Error::Timeout(format!(
                "{key}: no reply within {} s",
                timeout.as_secs_f64()
            ))),
        }
    }
}

impl Drop for Subscriber {
    fn drop(&mut self) {
        lock(&self.shared).closed = true;
        self.shared.1.notify_all();
        let _ = self.session.close().wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_names_checked() {
        let k = keys("veh01", "imu0").unwrap();
        assert_eq!(k.rate, "gyrotherm/veh01/imu0/rate");
        assert_eq!(k.calibration, "gyrotherm/veh01/imu0/calibration");
        for bad in ["", "a/b", "*", ".x", "-x", "a b", "é", &"x".repeat(65)] {
            let e = keys(bad, "imu0").unwrap_err().to_string();
            assert!(e.starts_with("vehicle name"), "{e}");
        }
        assert!(keys("v", "$")
            .unwrap_err()
            .to_string()
            .starts_with("sensor name"));
    }

    fn temp_file(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("gyrotherm-client-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn rust_locations_are_stripped_from_zenoh_errors() {
        let e = "Unable to connect to any of [tcp/127.0.0.1:1]! at /root/.cargo/registry/src/x/zenoh-1.10.2/src/net/runtime/orchestrator.rs:1013.";
        assert_eq!(
            zenoh_error_text(&e),
            "Unable to connect to any of [tcp/127.0.0.1:1]!"
        );
        let e = "bad value at line 3 at /a/b/config.rs:86:5. - Caused by x at /c/d.rs:2.";
        assert_eq!(zenoh_error_text(&e), "bad value at line 3 - Caused by x");
        assert_eq!(zenoh_error_text(&"look at me."), "look at me");
        let e = r#"JSON error: Message { msg: "unknown variant `server`, expected \"x\"", location: Some(Location { line: 1, column: 9 }) } at /a/config.rs:86."#;
        assert_eq!(
            zenoh_error_text(&e),
            r#"JSON error: unknown variant `server`, expected "x" (line 1, column 9)"#
        );
        let e = r#"JSON error: Message { msg: "eof", location: None }"#;
        assert_eq!(zenoh_error_text(&e), "JSON error: eof");
    }

    #[test]
    fn config_file_loaded_unchanged_placeholder_refused() {
        let text = r#"{ mode: "client", connect: { endpoints: ["tcp/127.0.0.1:7447"] },
            transport: { auth: { usrpwd: { user: "u", password: "REPLACE-WITH-A-SECRET" } } } }"#;
        let path = temp_file("placeholder.json5", text);
        let e = session_config_file(&path).unwrap_err().to_string();
        assert!(
            e.contains("placeholder.json5") && e.contains("still the shipped placeholder"),
            "{e}"
        );
        let path = temp_file("real.json5", &text.replace(PLACEHOLDER_PASSWORD, "s3cret"));
        let config = session_config_file(&path).unwrap();
        assert_eq!(config.get_json("mode").unwrap(), "\"client\"");
        assert_eq!(
            config.get_json("transport/auth/usrpwd/user").unwrap(),
            "\"u\""
        );
        // zenoh's own schema check, the file named, no Rust source location
        let path = temp_file("bad.json5", r#"{ mode: "server" }"#);
        let e = session_config_file(&path).unwrap_err().to_string();
        assert!(
            e.starts_with("zenoh config file ") && e.contains("bad.json5"),
            "{e}"
        );
        assert!(
            e.contains("unknown variant `server`") && e.ends_with("(line 1, column 9)"),
            "{e}"
        );
        assert!(!e.contains(".rs:") && !e.contains("Message {"), "{e}");
        for (key, endpoints) in [
            ("connect", r#"["quic/127.0.0.1:7447"]"#),
            ("listen", r#"{ router: [], peer: ["udp/127.0.0.1:0"] }"#),
        ] {
            let path = temp_file(
                "link.json5",
                &format!("{{ {key}: {{ endpoints: {endpoints} }} }}"),
            );
            let e = session_config_file(&path).unwrap_err().to_string();
            assert!(
                e.contains(&format!("{key}/endpoints")) && e.contains("tcp and tls links only"),
                "{e}"
            );
        }
        let path = temp_file(
            "links.json5",
            r#"{ connect: { endpoints: ["tcp/127.0.0.1:1", "tls/localhost:2"] } }"#,
        );
        assert!(session_config_file(&path).is_ok());
        let e = session_config_file("/nonexistent/z.json5")
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/z.json5"), "{e}");
        let e = Subscriber::from_config_file("a/b", "imu0", &path, 8)
            .err()
            .unwrap()
            .to_string();
        assert!(e.starts_with("vehicle name"), "{e}");
    }

    #[test]
    fn config_needs_an_endpoint() {
        assert!(session_config(&[]).is_err());
        assert!(session_config(&["tcp/127.0.0.1:7447".to_string()]).is_ok());
    }
}
