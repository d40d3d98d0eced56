//! Checked decoding of the daemon's msgpack payloads, schema version 1
//! (docs/wire-format.md; the same rules as `gyrotherm.codecs._wire_decode`).
//!
//! Every payload is one msgpack array: element 0 the message kind, element 1 the
//! schema version. The decoders check the kind, the version, the element count and
//! every field's type and range, and return a [`DecodeError`] naming the message,
//! the field, its index and the value. Trailing elements (fields appended within the
//! version) are ignored; unknown flag bits are kept. Integers are accepted where
//! floats are expected; `seq`, counters and flags must be unsigned integers.
//!
//! A rate message whose corrected, raw or bias value is NaN or ±inf is decoded with
//! [`flags::NON_FINITE`] added, so a servo loop testing `flags != 0` never takes it
//! for a clean sample.

use std::collections::BTreeMap;
use std::fmt;

use rmpv::Value;

/// The only schema version this decoder accepts.
pub const SCHEMA_VERSION: u64 = 1;

/// Message kinds (element 0).
pub mod kind {
    pub const RATE: u64 = 1;
    pub const STATE: u64 = 2;
    pub const HEALTH: u64 = 3;
    pub const CALIBRATION: u64 = 4;
}

/// Status flag bits (docs/wire-format.md, "Status flags").
pub mod flags {
    pub const TEMPERATURE_STALE: u64 = 0x01;
    pub const T_CLAMPED: u64 = 0x02;
    pub const DELTA_T_CLAMPED: u64 = 0x04;
    pub const NO_CALIBRATION: u64 = 0x08;
    pub const ESTIMATOR_REJECTED: u64 = 0x10;
    pub const COUNTER_JUMP: u64 = 0x20;
    pub const ESTIMATOR_WARMUP: u64 = 0x40;
    pub const RATE_SATURATED: u64 = 0x80;
    pub const SENSOR_FAULT: u64 = 0x100;
    /// Client side: a rate, raw rate or bias value is NaN or ±inf (set by the decoder).
    pub const NON_FINITE: u64 = 0x200;
    pub const BIAS_INVALID: u64 = 0x400;
    pub const T_ON_CLAMPED: u64 = 0x800;
    /// A boot-time zero is configured and not measured yet: the switch-on offset is in the rate.
    pub const ZERO_PENDING: u64 = 0x1000;
    /// The boot-time zero found no rest window before its deadline.
    pub const ZERO_FAILED: u64 = 0x2000;
    /// The boot-time zero in use could not be verified as taken at rest (after a restart,
    /// a first calibration or a clock step): a slow steady turn may be in it.
    pub const ZERO_UNVERIFIED: u64 = 0x4000;

    /// Every flag known to this version, with its name (as the Python `StatusFlags`).
    pub const ALL: [(u64, &str); 15] = [
        (TEMPERATURE_STALE, "TEMPERATURE_STALE"),
        (T_CLAMPED, "T_CLAMPED"),
        (DELTA_T_CLAMPED, "DELTA_T_CLAMPED"),
        (NO_CALIBRATION, "NO_CALIBRATION"),
        (ESTIMATOR_REJECTED, "ESTIMATOR_REJECTED"),
        (COUNTER_JUMP, "COUNTER_JUMP"),
        (ESTIMATOR_WARMUP, "ESTIMATOR_WARMUP"),
        (RATE_SATURATED, "RATE_SATURATED"),
        (SENSOR_FAULT, "SENSOR_FAULT"),
        (NON_FINITE, "NON_FINITE"),
        (BIAS_INVALID, "BIAS_INVALID"),
        (T_ON_CLAMPED, "T_ON_CLAMPED"),
        (ZERO_PENDING, "ZERO_PENDING"),
        (ZERO_FAILED, "ZERO_FAILED"),
        (ZERO_UNVERIFIED, "ZERO_UNVERIFIED"),
    ];

    /// The names of the bits set in `bits`, lowest first; a bit this version does
    /// not know (added by a newer daemon) is named by its value, e.g. `"0x8000"`.
    pub fn names(bits: u64) -> Vec<String> {
        (0..64)
            .map(|i| 1u64 << i)
            .filter(|bit| bits & bit != 0)
            .map(|bit| match ALL.iter().find(|(b, _)| *b == bit) {
                Some((_, name)) => (*name).to_string(),
                None => format!("{bit:#x}"),
            })
            .collect()
    }
}

/// A payload that does not follow the wire format; the text names the message,
/// the field, its index, the value and the problem, e.g.
/// `rate payload: field 'version' (index 1) = 2 is not the supported version 1`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DecodeError(pub String);

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for DecodeError {}

/// Rate message (kind 1): one per rate frame; rates in °/s.
#[derive(Debug, Clone, PartialEq)]
pub struct RateMessage {
    pub seq: u64,
    /// The CAN frame's time stamp, s.
    pub sensor_time_s: f64,
    /// Daemon wall clock when the frame arrived, s since the Unix epoch.
    pub receive_time_s: f64,
    /// Corrected rate x y z, °/s (`raw_rate_dps − bias_dps`).
    pub rate_dps: [f64; 3],
    /// The gyro's output as received, °/s.
    pub raw_rate_dps: [f64; 3],
    /// Thermal bias removed, °/s.
    pub bias_dps: [f64; 3],
    pub flags: u64,
}

/// Per-axis state of a calibration's effects (state element 13).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisEffects {
    pub structure_temperature_c: f64,
    pub hysteresis_h: f64,
    /// −1, 0 or 1.
    pub hysteresis_direction: i8,
    pub t_on_s: f64,
    pub effects_bias_dps: f64,
}

/// State message (kind 2): one per temperature frame.
#[derive(Debug, Clone, PartialEq)]
pub struct StateMessage {
    pub seq: u64,
    pub sensor_time_s: f64,
    pub receive_time_s: f64,
    /// Filtered gyro temperature T, °C (NaN: not available).
    pub temperature_c: f64,
    pub temperature_std_c: f64,
    /// Thermal gradient ΔT, °C.
    pub delta_t_c: f64,
    pub delta_t_std_c: f64,
    pub bias_dps: [f64; 3],
    pub flags: u64,
    /// Axis ("x", "y", "z") → effects; empty when the element is absent.
    pub effects: BTreeMap<String, AxisEffects>,
    /// The boot-time zero (state element 14); None when the daemon runs none.
    pub zero: Option<ZeroState>,
}

/// The boot-time zero in a state message (docs/model.md, "Boot-time zero").
#[derive(Debug, Clone, PartialEq)]
pub struct ZeroState {
    /// 0 off, 1 pending, 2 done, 3 failed.
    pub status: u8,
    /// z per axis (x, y, z), °/s; part of `bias_dps`; zeros unless done.
    pub offset_dps: [f64; 3],
}

/// Health message (kind 3).
#[derive(Debug, Clone, PartialEq)]
pub struct HealthMessage {
    pub seq: u64,
    /// Time stamp of the latest rate frame, s; `None` before the first one.
    pub sensor_time_s: Option<f64>,
    pub receive_time_s: f64,
    pub uptime_s: f64,
    pub frames_received: u64,
    pub frames_published: u64,
    /// Frames not published, by reason.
    pub drops: BTreeMap<String, u64>,
    pub flags: u64,
    /// `""` when no calibration is loaded.
    pub calibration_id: String,
    /// CAN counter jumps since start; 0 when the element is absent (older publishers).
    pub counter_jumps: u64,
}

/// Reply of the calibration queryable (kind 4).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationInfo {
    pub calibration_id: String,
    /// The loaded calibration as a msgpack map with string keys; `None` when none is loaded.
    pub calibration: Option<Value>,
    pub health: Option<HealthMessage>,
}

type R<T> = Result<T, DecodeError>;

fn shown(v: &Value) -> String {
    let s = match v {
        Value::String(s) if s.as_str().is_some() => format!("'{}'", s.as_str().unwrap_or("")),
        Value::Nil => "nil".to_string(),
        other => other.to_string(),
    };
    if s.chars().count() > 60 {
        let mut t: String = s.chars().take(57).collect();
        t.push_str("...");
        t
    } else {
        s
    }
}

fn type_name(v: &Value) -> &'static str {
    match v {
        Value::Nil => "nil",
        Value::Boolean(_) => "bool",
        Value::Integer(i) if i.is_u64() => "uint",
        Value::Integer(_) => "negative int",
        Value::F32(_) | Value::F64(_) => "float",
        Value::String(_) => "str",
        Value::Binary(_) => "bin",
        Value::Array(_) => "array",
        Value::Map(_) => "map",
        Value::Ext(..) => "ext",
    }
}

fn fail(what: &str, index: usize, name: &str, v: &Value, problem: &str) -> DecodeError {
    DecodeError(format!(
        "{what} payload: field '{name}' (index {index}) = {} {problem}",
        shown(v)
    ))
}

/// The field under decoding: message name, index, field name.
struct F<'a> {
    what: &'a str,
    i: usize,
    name: &'a str,
}

impl F<'_> {
    fn fail(&self, v: &Value, problem: &str) -> DecodeError {
        fail(self.what, self.i, self.name, v, problem)
    }

    fn u64(&self, v: &Value) -> R<u64> {
        match v {
            Value::Integer(i) => i
                .as_u64()
                .ok_or_else(|| self.fail(v, &format!("is out of range [0, {}]", u64::MAX))),
            _ => Err(self.fail(v, &format!("is {}, expected uint64", type_name(v)))),
        }
    }

    fn float(&self, v: &Value) -> R<f64> {
        match v {
            Value::F64(f) => Ok(*f),
            Value::F32(f) => Ok(f64::from(*f)),
            Value::Integer(i) => i
                .as_f64()
                .ok_or_else(|| self.fail(v, "is not representable as float")),
            _ => Err(self.fail(v, &format!("is {}, expected float", type_name(v)))),
        }
    }

    fn finite(&self, v: &Value) -> R<f64> {
        let f = self.float(v)?;
        if f.is_finite() {
            Ok(f)
        } else {
            Err(self.fail(v, "is not finite"))
        }
    }

    fn opt_finite(&self, v: &Value) -> R<Option<f64>> {
        match v {
            Value::Nil => Ok(None),
            _ => self.finite(v).map(Some),
        }
    }

    fn str(&self, v: &Value) -> R<String> {
        match v {
            Value::String(s) => s
                .as_str()
                .map(str::to_owned)
                .ok_or_else(|| self.fail(v, "is not valid UTF-8")),
            _ => Err(self.fail(v, &format!("is {}, expected str", type_name(v)))),
        }
    }

    fn sub<'b>(&'b self, name: &'b str) -> F<'b> {
        F {
            what: self.what,
            i: self.i,
            name,
        }
    }

    fn drops(&self, v: &Value) -> R<BTreeMap<String, u64>> {
        let Value::Map(m) = v else {
            return Err(self.fail(v, &format!("is {}, expected map str→uint64", type_name(v))));
        };
        let key_field = format!("{} key", self.name);
        let mut out = BTreeMap::new();
        for (k, c) in m {
            let reason = self.sub(&key_field).str(k)?;
            let count_field = format!("{}['{reason}']", self.name);
            let count = self.sub(&count_field).u64(c)?;
            out.insert(reason, count);
        }
        Ok(out)
    }

    fn calibration(&self, v: &Value) -> R<Option<Value>> {
        match v {
            Value::Nil => Ok(None),
            Value::Map(m) => {
                let key_field = format!("{} key", self.name);
                for (k, _) in m {
                    self.sub(&key_field).str(k)?;
                }
                Ok(Some(v.clone()))
            }
            _ => Err(self.fail(v, &format!("is {}, expected map or nil", type_name(v)))),
        }
    }

    fn zero(&self, v: &Value) -> R<ZeroState> {
        let a = match v {
            Value::Array(a) if a.len() >= 4 => a,
            _ => return Err(self.fail(v, "is not an array of 4 elements")),
        };
        let status_field = format!("{}.status", self.name);
        let status = match a[0].as_u64() {
            Some(s @ 0..=3) => s as u8,
            _ => return Err(self.sub(&status_field).fail(&a[0], "is not 0, 1, 2 or 3")),
        };
        let at = |k: usize| format!("{}.offset_dps[{k}]", self.name);
        Ok(ZeroState {
            status,
            offset_dps: [
                self.sub(&at(0)).float(&a[1])?,
                self.sub(&at(1)).float(&a[2])?,
                self.sub(&at(2)).float(&a[3])?,
            ],
        })
    }

    fn effects(&self, v: &Value) -> R<BTreeMap<String, AxisEffects>> {
        let Value::Map(m) = v else {
            return Err(self.fail(v, &format!("is {}, expected map axis→array", type_name(v))));
        };
        let mut out = BTreeMap::new();
        for (k, e) in m {
            let key_field = format!("{} key", self.name);
            let axis = self.sub(&key_field).str(k)?;
            if !matches!(axis.as_str(), "x" | "y" | "z") {
                return Err(self
                    .sub(&key_field)
                    .fail(k, "is not an axis ('x', 'y', 'z')"));
            }
            let at = format!("{}['{axis}']", self.name);
            let a = match e {
                Value::Array(a) if a.len() >= 5 => a,
                _ => return Err(self.sub(&at).fail(e, "is not an array of 5 elements")),
            };
            let dir_field = format!("{at}.hysteresis_direction");
            let direction = match a[2].as_i64() {
                Some(d @ -1..=1) if a[2].is_i64() || a[2].is_u64() => d as i8,
                _ => return Err(self.sub(&dir_field).fail(&a[2], "is not -1, 0 or 1")),
            };
            let name = |n: &str| format!("{at}.{n}");
            out.insert(
                axis,
                AxisEffects {
                    structure_temperature_c: self
                        .sub(&name("structure_temperature_c"))
                        .float(&a[0])?,
                    hysteresis_h: self.sub(&name("hysteresis_h")).float(&a[1])?,
                    hysteresis_direction: direction,
                    t_on_s: self.sub(&name("t_on_s")).float(&a[3])?,
                    effects_bias_dps: self.sub(&name("effects_bias_dps")).float(&a[4])?,
                },
            );
        }
        Ok(out)
    }
}

fn kind_name(k: u64) -> Option<&'static str> {
    match k {
        kind::RATE => Some("rate"),
        kind::STATE => Some("state"),
        kind::HEALTH => Some("health"),
        kind::CALIBRATION => Some("calibration"),
        _ => None,
    }
}

/// Check kind, version and element count; return the array.
fn header<'a>(a: &'a [Value], k: u64, what: &str, names: &[&str]) -> R<&'a [Value]> {
    if a.len() < 2 {
        return Err(DecodeError(format!(
            "{what} payload: array has {} elements, expected kind and version",
            a.len()
        )));
    }
    if a[0].as_u64() != Some(k) {
        let got = a[0]
            .as_u64()
            .and_then(kind_name)
            .map(|n| format!("({n}) "))
            .unwrap_or_default();
        return Err(fail(
            what,
            0,
            "kind",
            &a[0],
            &format!("{got}is not {k} ({})", kind_name(k).unwrap_or("?")),
        ));
    }
    if a[1].as_u64() != Some(SCHEMA_VERSION) {
        return Err(fail(
            what,
            1,
            "version",
            &a[1],
            &format!("is not the supported version {SCHEMA_VERSION}"),
        ));
    }
    let expected = 2 + names.len();
    if a.len() < expected {
        return Err(DecodeError(format!(
            "{what} payload: missing field '{}' (index {}): array has {} elements, expected {expected}",
            names[a.len() - 2],
            a.len(),
            a.len()
        )));
    }
    Ok(a)
}

fn unpack(payload: &[u8], what: &str) -> R<Vec<Value>> {
    let mut cursor = payload;
    let value = rmpv::decode::read_value(&mut cursor).map_err(|e| {
        DecodeError(format!(
            "{what} payload: not valid msgpack ({} bytes): {e}",
            payload.len()
        ))
    })?;
    if !cursor.is_empty() {
        return Err(DecodeError(format!(
            "{what} payload: not valid msgpack ({} bytes): ExtraData: {} bytes after the array",
            payload.len(),
            cursor.len()
        )));
    }
    match value {
        Value::Array(a) => Ok(a),
        other => Err(DecodeError(format!(
            "{what} payload: expected a msgpack array, got {}",
            type_name(&other)
        ))),
    }
}

const RATE_FIELDS: [&str; 13] = [
    "seq",
    "sensor_time_s",
    "receive_time_s",
    "rate_dps[0]",
    "rate_dps[1]",
    "rate_dps[2]",
    "raw_rate_dps[0]",
    "raw_rate_dps[1]",
    "raw_rate_dps[2]",
    "bias_dps[0]",
    "bias_dps[1]",
    "bias_dps[2]",
    "flags",
];
const STATE_FIELDS: [&str; 11] = [
    "seq",
    "sensor_time_s",
    "receive_time_s",
    "temperature_c",
    "temperature_std_c",
    "delta_t_c",
    "delta_t_std_c",
    "bias_dps[0]",
    "bias_dps[1]",
    "bias_dps[2]",
    "flags",
];
const HEALTH_FIELDS: [&str; 9] = [
    "seq",
    "sensor_time_s",
    "receive_time_s",
    "uptime_s",
    "frames_received",
    "frames_published",
    "drops",
    "flags",
    "calibration_id",
];
const CALIBRATION_FIELDS: [&str; 3] = ["calibration_id", "calibration", "health"];

fn field<'a>(what: &'a str, names: &'a [&'a str], i: usize) -> F<'a> {
    F {
        what,
        i,
        name: names[i - 2],
    }
}

fn vec3(what: &str, names: &[&str], a: &[Value], first: usize) -> R<[f64; 3]> {
    Ok([
        field(what, names, first).float(&a[first])?,
        field(what, names, first + 1).float(&a[first + 1])?,
        field(what, names, first + 2).float(&a[first + 2])?,
    ])
}

/// Decode a rate payload. Flags gain [`flags::NON_FINITE`] when a rate, raw rate or
/// bias value is NaN or ±inf.
pub fn decode_rate(payload: &[u8]) -> Result<RateMessage, DecodeError> {
    let a = unpack(payload, "rate")?;
    rate_from(&a, "rate")
}

fn rate_from(a: &[Value], what: &str) -> R<RateMessage> {
    let n = &RATE_FIELDS;
    let a = header(a, kind::RATE, what, n)?;
    let mut m = RateMessage {
        seq: field(what, n, 2).u64(&a[2])?,
        sensor_time_s: field(what, n, 3).finite(&a[3])?,
        receive_time_s: field(what, n, 4).finite(&a[4])?,
        rate_dps: vec3(what, n, a, 5)?,
        raw_rate_dps: vec3(what, n, a, 8)?,
        bias_dps: vec3(what, n, a, 11)?,
        flags: field(what, n, 14).u64(&a[14])?,
    };
    let all = m.rate_dps.iter().chain(&m.raw_rate_dps).chain(&m.bias_dps);
    if !all.into_iter().all(|v| v.is_finite()) {
        m.flags |= flags::NON_FINITE;
    }
    Ok(m)
}

/// Decode a state payload (with or without the appended `effects` and `zero` elements).
pub fn decode_state(payload: &[u8]) -> Result<StateMessage, DecodeError> {
    let a = unpack(payload, "state")?;
    let (what, n) = ("state", &STATE_FIELDS);
    let a = header(&a, kind::STATE, what, n)?;
    let effects = match a.get(13) {
        Some(v) => F {
            what,
            i: 13,
            name: "effects",
        }
        .effects(v)?,
        None => BTreeMap::new(),
    };
    let zero = match a.get(14) {
        Some(v) => Some(
            F {
                what,
                i: 14,
                name: "zero",
            }
            .zero(v)?,
        ),
        None => None,
    };
    Ok(StateMessage {
        seq: field(what, n, 2).u64(&a[2])?,
        sensor_time_s: field(what, n, 3).finite(&a[3])?,
        receive_time_s: field(what, n, 4).finite(&a[4])?,
        temperature_c: field(what, n, 5).float(&a[5])?,
        temperature_std_c: field(what, n, 6).float(&a[6])?,
        delta_t_c: field(what, n, 7).float(&a[7])?,
        delta_t_std_c: field(what, n, 8).float(&a[8])?,
        bias_dps: vec3(what, n, a, 9)?,
        flags: field(what, n, 12).u64(&a[12])?,
        effects,
        zero,
    })
}

/// Decode a health payload (with or without the appended `counter_jumps` element).
pub fn decode_health(payload: &[u8]) -> Result<HealthMessage, DecodeError> {
    let a = unpack(payload, "health")?;
    health_from(&a, "health")
}

fn health_from(a: &[Value], what: &str) -> R<HealthMessage> {
    let n = &HEALTH_FIELDS;
    let a = header(a, kind::HEALTH, what, n)?;
    let counter_jumps = match a.get(11) {
        Some(v) => F {
            what,
            i: 11,
            name: "counter_jumps",
        }
        .u64(v)?,
        None => 0,
    };
    Ok(HealthMessage {
        seq: field(what, n, 2).u64(&a[2])?,
        sensor_time_s: field(what, n, 3).opt_finite(&a[3])?,
        receive_time_s: field(what, n, 4).finite(&a[4])?,
        uptime_s: field(what, n, 5).finite(&a[5])?,
        frames_received: field(what, n, 6).u64(&a[6])?,
        frames_published: field(what, n, 7).u64(&a[7])?,
        drops: field(what, n, 8).drops(&a[8])?,
        flags: field(what, n, 9).u64(&a[9])?,
        calibration_id: field(what, n, 10).str(&a[10])?,
        counter_jumps,
    })
}

/// Decode the calibration queryable's reply.
pub fn decode_calibration_info(payload: &[u8]) -> Result<CalibrationInfo, DecodeError> {
    let a = unpack(payload, "calibration")?;
    let (what, n) = ("calibration", &CALIBRATION_FIELDS);
    let a = header(&a, kind::CALIBRATION, what, n)?;
    let health = match &a[4] {
        Value::Nil => None,
        Value::Array(h) => Some(health_from(h, "calibration.health")?),
        v => {
            return Err(field(what, n, 4).fail(
                v,
                &format!("is {}, expected health array or nil", type_name(v)),
            ))
        }
    };
    Ok(CalibrationInfo {
        calibration_id: field(what, n, 2).str(&a[2])?,
        calibration: field(what, n, 3).calibration(&a[3])?,
        health,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flag_names_lowest_first_unknown_bits_by_value() {
        assert!(flags::names(0).is_empty());
        assert_eq!(
            flags::names(flags::NON_FINITE | flags::TEMPERATURE_STALE | 0x8000),
            ["TEMPERATURE_STALE", "NON_FINITE", "0x8000"]
        );
    }

    fn pack(v: Value) -> Vec<u8> {
        let mut out = Vec::new();
        rmpv::encode::write_value(&mut out, &v).unwrap();
        out
    }

    fn rate_array() -> Vec<Value> {
        let mut a = vec![Value::from(1u64), Value::from(1u64), Value::from(7u64)];
        a.extend((0..11).map(|k| Value::from(k as f64)));
        a.push(Value::from(0u64));
        a
    }

    #[test]
    fn integers_accepted_as_floats() {
        let mut a = rate_array();
        a[5] = Value::from(2u64);
        a[6] = Value::from(-3i64);
        let m = decode_rate(&pack(Value::Array(a))).unwrap();
        assert_eq!(m.rate_dps, [2.0, -3.0, 4.0]);
        assert_eq!(m.flags, 0);
    }

    #[test]
    fn errors_name_field_index_value() {
        let mut a = rate_array();
        a[1] = Value::from(2u64);
        let e = decode_rate(&pack(Value::Array(a))).unwrap_err();
        assert_eq!(
            e.0,
            "rate payload: field 'version' (index 1) = 2 is not the supported version 1"
        );

        let mut a = rate_array();
        a.pop();
        let e = decode_rate(&pack(Value::Array(a))).unwrap_err();
        assert_eq!(
            e.0,
            "rate payload: missing field 'flags' (index 14): array has 14 elements, expected 15"
        );

        let mut a = rate_array();
        a[2] = Value::from(-1i64);
        let e = decode_rate(&pack(Value::Array(a))).unwrap_err();
        assert_eq!(
            e.0,
            "rate payload: field 'seq' (index 2) = -1 is out of range [0, 18446744073709551615]"
        );

        let mut a = rate_array();
        a[6] = Value::from("x");
        let e = decode_rate(&pack(Value::Array(a))).unwrap_err();
        assert_eq!(
            e.0,
            "rate payload: field 'rate_dps[1]' (index 6) = 'x' is str, expected float"
        );

        let mut a = rate_array();
        a[0] = Value::from(2u64);
        let e = decode_rate(&pack(Value::Array(a))).unwrap_err();
        assert_eq!(
            e.0,
            "rate payload: field 'kind' (index 0) = 2 (state) is not 1 (rate)"
        );

        let mut a = rate_array();
        a[3] = Value::from(f64::NAN);
        let e = decode_rate(&pack(Value::Array(a))).unwrap_err();
        assert!(
            e.0.starts_with("rate payload: field 'sensor_time_s' (index 3) = "),
            "{e}"
        );
        assert!(e.0.ends_with("is not finite"), "{e}");

        let e = decode_rate(&[0x93, 0x01]).unwrap_err();
        assert!(
            e.0.starts_with("rate payload: not valid msgpack (2 bytes)"),
            "{e}"
        );
        let mut bytes = pack(Value::Array(rate_array()));
        bytes.push(0);
        let e = decode_rate(&bytes).unwrap_err();
        assert!(e.0.contains("ExtraData"), "{e}");
        let e = decode_rate(&pack(Value::from(1u64))).unwrap_err();
        assert_eq!(e.0, "rate payload: expected a msgpack array, got uint");
    }

    #[test]
    fn non_finite_rate_is_flagged() {
        let mut a = rate_array();
        a[9] = Value::from(f64::INFINITY);
        let m = decode_rate(&pack(Value::Array(a))).unwrap();
        assert_eq!(m.flags, flags::NON_FINITE);
    }

    #[test]
    fn trailing_elements_ignored_and_unknown_bits_kept() {
        let mut a = rate_array();
        a[14] = Value::from(0x1000u64 | flags::SENSOR_FAULT);
        a.push(Value::from("future field"));
        let m = decode_rate(&pack(Value::Array(a))).unwrap();
        assert_eq!(m.flags, 0x1000 | flags::SENSOR_FAULT);
    }
}
