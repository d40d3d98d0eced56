//! Decodes every vector of the shared, language-neutral tests/vectors/wire-v1.json
//! (read at test time from the repository, not copied) and compares every field.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;

use gyrotherm_client::decode::{
    decode_calibration_info, decode_health, decode_rate, decode_state, AxisEffects, HealthMessage,
    ZeroState,
};
use serde_json::Value as J;

fn vectors_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/vectors/wire-v1.json")
}

fn load() -> J {
    let path = vectors_path();
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn hex(s: &str) -> Vec<u8> {
    assert!(s.len().is_multiple_of(2), "odd hex length");
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

/// Expected float: a JSON number, or the string "NaN" (the file's "not available").
fn want_f64(want: &J, at: &str) -> f64 {
    match want {
        J::String(s) if s == "NaN" => f64::NAN,
        J::Number(n) => n.as_f64().unwrap(),
        other => panic!("{at}: expected value {other} is not a float"),
    }
}

fn eq_f64(got: f64, want: &J, at: &str) {
    let w = want_f64(want, at);
    // bit-exact: both sides are the same float 64 the encoder wrote
    assert!(
        (w.is_nan() && got.is_nan()) || got.to_bits() == w.to_bits(),
        "{at}: decoded {got:?}, vector says {w:?}"
    );
}

fn eq_u64(got: u64, want: &J, at: &str) {
    assert_eq!(
        Some(got),
        want.as_u64(),
        "{at}: decoded {got}, vector says {want}"
    );
}

fn eq_f64x3(got: &[f64; 3], want: &J, at: &str) {
    let w = want
        .as_array()
        .unwrap_or_else(|| panic!("{at}: expected value is not an array"));
    assert_eq!(w.len(), 3, "{at}: expected value has {} elements", w.len());
    for k in 0..3 {
        eq_f64(got[k], &w[k], &format!("{at}[{k}]"));
    }
}

fn eq_str(got: &str, want: &J, at: &str) {
    assert_eq!(
        Some(got),
        want.as_str(),
        "{at}: decoded {got:?}, vector says {want}"
    );
}

fn fields(v: &J) -> Vec<(String, J)> {
    v["fields"]
        .as_array()
        .expect("fields")
        .iter()
        .map(|f| {
            (
                f["name"].as_str().expect("field name").to_owned(),
                f["value"].clone(),
            )
        })
        .collect()
}

/// msgpack value (the calibration map) against its JSON form.
fn eq_msgpack(got: &rmpv::Value, want: &J, at: &str) {
    use rmpv::Value as M;
    match (got, want) {
        (M::Nil, J::Null) => {}
        (M::Boolean(a), J::Bool(b)) => assert_eq!(a, b, "{at}"),
        (M::Integer(a), J::Number(b)) if b.is_u64() || b.is_i64() => {
            assert_eq!(a.as_i64(), b.as_i64(), "{at}: decoded {a}, vector says {b}");
            assert_eq!(a.as_u64(), b.as_u64(), "{at}: decoded {a}, vector says {b}");
        }
        (M::F64(a), _) => eq_f64(*a, want, at),
        (M::String(a), J::String(b)) => assert_eq!(a.as_str(), Some(b.as_str()), "{at}"),
        (M::Array(a), J::Array(b)) => {
            assert_eq!(a.len(), b.len(), "{at}: array length");
            for (k, (x, y)) in a.iter().zip(b).enumerate() {
                eq_msgpack(x, y, &format!("{at}[{k}]"));
            }
        }
        (M::Map(a), J::Object(b)) => {
            assert_eq!(a.len(), b.len(), "{at}: map size");
            for (k, x) in a {
                let key = k
                    .as_str()
                    .unwrap_or_else(|| panic!("{at}: non-string key {k}"));
                let y = b
                    .get(key)
                    .unwrap_or_else(|| panic!("{at}: decoded key {key:?} not in the vector"));
                eq_msgpack(x, y, &format!("{at}.{key}"));
            }
        }
        _ => panic!("{at}: decoded {got}, vector says {want}"),
    }
}

fn check_effects(got: &BTreeMap<String, AxisEffects>, want: &J, at: &str) {
    let w = want
        .as_object()
        .unwrap_or_else(|| panic!("{at}: expected value is not a map"));
    let got_axes: BTreeSet<&str> = got.keys().map(String::as_str).collect();
    let want_axes: BTreeSet<&str> = w.keys().map(String::as_str).collect();
    assert_eq!(got_axes, want_axes, "{at}: axes");
    for (axis, e) in got {
        let we = &w[axis];
        let a = format!("{at}.{axis}");
        let names: BTreeSet<&str> = we.as_object().unwrap().keys().map(String::as_str).collect();
        let expected_names: BTreeSet<&str> = [
            "structure_temperature_c",
            "hysteresis_h",
            "hysteresis_direction",
            "t_on_s",
            "effects_bias_dps",
        ]
        .into();
        assert_eq!(names, expected_names, "{a}: effect fields");
        eq_f64(
            e.structure_temperature_c,
            &we["structure_temperature_c"],
            &format!("{a}.structure_temperature_c"),
        );
        eq_f64(
            e.hysteresis_h,
            &we["hysteresis_h"],
            &format!("{a}.hysteresis_h"),
        );
        assert_eq!(
            Some(i64::from(e.hysteresis_direction)),
            we["hysteresis_direction"].as_i64(),
            "{a}.hysteresis_direction"
        );
        eq_f64(e.t_on_s, &we["t_on_s"], &format!("{a}.t_on_s"));
        eq_f64(
            e.effects_bias_dps,
            &we["effects_bias_dps"],
            &format!("{a}.effects_bias_dps"),
        );
    }
}

fn check_zero(got: &Option<ZeroState>, want: &J, at: &str) {
    let z = got
        .as_ref()
        .unwrap_or_else(|| panic!("{at}: no zero decoded, vector says {want}"));
    assert_eq!(
        Some(u64::from(z.status)),
        want["status"].as_u64(),
        "{at}.status"
    );
    eq_f64x3(
        &z.offset_dps,
        &want["offset_dps"],
        &format!("{at}.offset_dps"),
    );
}

fn check_health(h: &HealthMessage, want_fields: &[(String, J)], at: &str) {
    let mut seen = BTreeSet::new();
    for (name, want) in want_fields {
        let a = format!("{at}.{name}");
        match name.as_str() {
            "kind" => eq_u64(3, want, &a),
            "version" => eq_u64(1, want, &a),
            "seq" => eq_u64(h.seq, want, &a),
            "sensor_time_s" => match h.sensor_time_s {
                None => assert!(want.is_null(), "{a}: decoded None, vector says {want}"),
                Some(t) => eq_f64(t, want, &a),
            },
            "receive_time_s" => eq_f64(h.receive_time_s, want, &a),
            "uptime_s" => eq_f64(h.uptime_s, want, &a),
            "frames_received" => eq_u64(h.frames_received, want, &a),
            "frames_published" => eq_u64(h.frames_published, want, &a),
            "drops" => {
                let w = want.as_object().expect("drops map");
                assert_eq!(h.drops.len(), w.len(), "{a}: size");
                for (reason, count) in &h.drops {
                    eq_u64(*count, &w[reason], &format!("{a}[{reason:?}]"));
                }
            }
            "flags" => eq_u64(h.flags, want, &a),
            "calibration_id" => eq_str(&h.calibration_id, want, &a),
            "counter_jumps" => eq_u64(h.counter_jumps, want, &a),
            other => panic!("{a}: field {other:?} unknown to this test: decoder out of date?"),
        }
        seen.insert(name.as_str());
    }
    if !seen.contains("counter_jumps") {
        // appended in schema 1: absent from older publishers, decoded as 0
        assert_eq!(
            h.counter_jumps, 0,
            "{at}: counter_jumps absent but decoded {}",
            h.counter_jumps
        );
    }
}

#[test]
fn every_vector_decodes_to_its_fields() {
    let doc = load();
    assert_eq!(doc["format"], "gyrotherm-wire-vectors");
    assert_eq!(doc["schema_version"], 1);
    let vectors = doc["vectors"].as_array().expect("vectors");
    let mut kinds_seen = BTreeMap::<String, usize>::new();
    for v in vectors {
        let name = v["name"].as_str().expect("name");
        let kind = v["kind"].as_str().expect("kind");
        let bytes = hex(v["hex"].as_str().expect("hex"));
        assert_eq!(
            Some(bytes.len() as u64),
            v["length"].as_u64(),
            "{name}: length"
        );
        assert_eq!(v["schema_version"], 1, "{name}: schema_version");
        *kinds_seen.entry(kind.to_owned()).or_default() += 1;
        let fs = fields(v);
        let mut names = BTreeSet::new();
        match kind {
            "rate" => {
                let m = decode_rate(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
                for (f, want) in &fs {
                    let a = format!("{name}.{f}");
                    match f.as_str() {
                        "kind" => eq_u64(1, want, &a),
                        "version" => eq_u64(1, want, &a),
                        "seq" => eq_u64(m.seq, want, &a),
                        "sensor_time_s" => eq_f64(m.sensor_time_s, want, &a),
                        "receive_time_s" => eq_f64(m.receive_time_s, want, &a),
                        "rate_dps" => eq_f64x3(&m.rate_dps, want, &a),
                        "raw_rate_dps" => eq_f64x3(&m.raw_rate_dps, want, &a),
                        "bias_dps" => eq_f64x3(&m.bias_dps, want, &a),
                        "flags" => eq_u64(m.flags, want, &a),
                        other => panic!("{a}: field {other:?} unknown to this test"),
                    }
                    names.insert(f.clone());
                }
                assert_eq!(names.len(), 9, "{name}: every rate field listed");
            }
            "state" => {
                let m = decode_state(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
                for (f, want) in &fs {
                    let a = format!("{name}.{f}");
                    match f.as_str() {
                        "kind" => eq_u64(2, want, &a),
                        "version" => eq_u64(1, want, &a),
                        "seq" => eq_u64(m.seq, want, &a),
                        "sensor_time_s" => eq_f64(m.sensor_time_s, want, &a),
                        "receive_time_s" => eq_f64(m.receive_time_s, want, &a),
                        "temperature_c" => eq_f64(m.temperature_c, want, &a),
                        "temperature_std_c" => eq_f64(m.temperature_std_c, want, &a),
                        "delta_t_c" => eq_f64(m.delta_t_c, want, &a),
                        "delta_t_std_c" => eq_f64(m.delta_t_std_c, want, &a),
                        "bias_dps" => eq_f64x3(&m.bias_dps, want, &a),
                        "flags" => eq_u64(m.flags, want, &a),
                        "effects" => check_effects(&m.effects, want, &a),
                        "zero" => check_zero(&m.zero, want, &a),
                        other => panic!("{a}: field {other:?} unknown to this test"),
                    }
                    names.insert(f.clone());
                }
                if !names.contains("zero") {
                    assert!(
                        m.zero.is_none(),
                        "{name}: no zero element, decoded {:?}",
                        m.zero
                    );
                }
                if !names.contains("effects") {
                    assert!(
                        m.effects.is_empty(),
                        "{name}: no effects element, decoded {:?}",
                        m.effects
                    );
                }
                assert!(names.len() >= 11, "{name}: every state field listed");
            }
            "health" => {
                let h = decode_health(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
                check_health(&h, &fs, name);
                assert!(fs.len() >= 11, "{name}: every health field listed");
            }
            "calibration" => {
                let c = decode_calibration_info(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
                for (f, want) in &fs {
                    let a = format!("{name}.{f}");
                    match f.as_str() {
                        "kind" => eq_u64(4, want, &a),
                        "version" => eq_u64(1, want, &a),
                        "calibration_id" => eq_str(&c.calibration_id, want, &a),
                        "calibration" => match &c.calibration {
                            None => {
                                assert!(want.is_null(), "{a}: decoded None, vector says {want}")
                            }
                            Some(cal) => eq_msgpack(cal, want, &a),
                        },
                        "health" => match &c.health {
                            None => {
                                assert!(want.is_null(), "{a}: decoded None, vector says {want}")
                            }
                            Some(h) => {
                                let hf: Vec<(String, J)> = want
                                    .as_array()
                                    .expect("health fields")
                                    .iter()
                                    .map(|x| {
                                        (x["name"].as_str().unwrap().to_owned(), x["value"].clone())
                                    })
                                    .collect();
                                check_health(h, &hf, &a);
                            }
                        },
                        other => panic!("{a}: field {other:?} unknown to this test"),
                    }
                    names.insert(f.clone());
                }
                assert_eq!(names.len(), 5, "{name}: every calibration field listed");
            }
            other => panic!("{name}: kind {other:?} unknown to this test"),
        }
    }
    // every message kind is covered, with both forms of state and health
    assert!(
        kinds_seen.get("rate").copied().unwrap_or(0) >= 2,
        "{kinds_seen:?}"
    );
    assert!(
        kinds_seen.get("state").copied().unwrap_or(0) >= 2,
        "{kinds_seen:?}"
    );
    assert!(
        kinds_seen.get("health").copied().unwrap_or(0) >= 2,
        "{kinds_seen:?}"
    );
    assert!(
        kinds_seen.get("calibration").copied().unwrap_or(0) >= 1,
        "{kinds_seen:?}"
    );
    eprintln!("decoded {} vectors: {kinds_seen:?}", vectors.len());
}

#[test]
fn decoders_refuse_other_kinds() {
    let doc = load();
    for v in doc["vectors"].as_array().unwrap() {
        let bytes = hex(v["hex"].as_str().unwrap());
        let kind = v["kind"].as_str().unwrap();
        let results = [
            ("rate", decode_rate(&bytes).err()),
            ("state", decode_state(&bytes).err()),
            ("health", decode_health(&bytes).err()),
            ("calibration", decode_calibration_info(&bytes).err()),
        ];
        for (decoder, err) in results {
            if decoder == kind {
                assert!(err.is_none(), "{}: {err:?}", v["name"]);
            } else {
                let e = err
                    .unwrap_or_else(|| panic!("{}: decode_{decoder} accepted a {kind}", v["name"]));
                assert!(
                    e.0.starts_with(&format!("{decoder} payload: field 'kind' (index 0) = ")),
                    "{}: {e}",
                    v["name"]
                );
            }
        }
    }
}

#[test]
fn every_truncation_and_wrong_version_is_an_error() {
    let doc = load();
    for v in doc["vectors"].as_array().unwrap() {
        let bytes = hex(v["hex"].as_str().unwrap());
        let kind = v["kind"].as_str().unwrap();
        let decode = |b: &[u8]| -> Result<(), String> {
            match kind {
                "rate" => decode_rate(b).map(drop),
                "state" => decode_state(b).map(drop),
                "health" => decode_health(b).map(drop),
                _ => decode_calibration_info(b).map(drop),
            }
            .map_err(|e| e.0)
        };
        for cut in 0..bytes.len() {
            let e = decode(&bytes[..cut]).expect_err("truncated payload accepted");
            assert!(
                e.contains("not valid msgpack"),
                "{}: cut {cut}: {e}",
                v["name"]
            );
        }
        // element 1 is the version, a positive fixint right after the array header
        let mut wrong = bytes.clone();
        let at = if bytes[0] & 0xf0 == 0x90 { 2 } else { 4 };
        assert_eq!(wrong[at], 1, "{}: version byte", v["name"]);
        wrong[at] = 2;
        let e = decode(&wrong).expect_err("version 2 accepted");
        assert!(
            e.ends_with("field 'version' (index 1) = 2 is not the supported version 1"),
            "{}: {e}",
            v["name"]
        );
    }
}

#[test]
fn flag_names_and_bits_match_the_vectors_file() {
    // the vectors file lists the Python StatusFlags: same names, same bits, no more
    let doc = load();
    let want: BTreeMap<String, u64> = doc["flags"]
        .as_object()
        .expect("flags")
        .iter()
        .map(|(k, v)| (k.clone(), v.as_u64().expect("flag bit")))
        .collect();
    let got: BTreeMap<String, u64> = gyrotherm_client::decode::flags::ALL
        .iter()
        .map(|(bit, name)| ((*name).to_string(), *bit))
        .collect();
    assert_eq!(got, want);
    for (name, bit) in &want {
        assert_eq!(
            gyrotherm_client::decode::flags::names(*bit),
            vec![name.clone()]
        );
    }
}
