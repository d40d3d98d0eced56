//! Rust client of the gyrotherm daemon (thermal zero-bias compensation of MEMS gyros).
//!
//! The daemon publishes msgpack arrays on Eclipse Zenoh keys
//! `gyrotherm/<vehicle>/<sensor>/{rate,state,health}` and answers a calibration
//! queryable (docs/wire-format.md). This crate has the same decoding ([`decode`]),
//! gap detection and latency statistics ([`stats`]) as the Python
//! `gyrotherm.client.Subscriber`, and a [`Subscriber`] of the rate stream. The session
//! comes from endpoints ([`Subscriber::connect`]) or from a Zenoh configuration file
//! ([`Subscriber::from_config_file`]: router login, mutual TLS).
//!
//! ```no_run
//! use std::time::Duration;
//! let gyro = gyrotherm_client::Subscriber::connect(
//!     "veh01", "imu0", &["tcp/127.0.0.1:7447".to_string()], 1024).unwrap();
//! for sample in gyro.rates(Duration::from_secs(1)) {
//!     if sample.flags != 0 {
//!         continue; // not clean: stale T, clamped, invalid bias, non-finite …
//!     }
//!     let [_x_dps, _y_dps, _z_dps] = sample.rate_dps; // bias removed, °/s
//! }
//! ```

pub mod decode;
pub mod stats;
pub mod subscriber;

pub use decode::{
    decode_calibration_info, decode_health, decode_rate, decode_state, CalibrationInfo,
    DecodeError, HealthMessage, RateMessage, StateMessage, ZeroState,
};
pub use stats::{LatencyStats, StreamStats};
pub use subscriber::{
    keys, session_config, session_config_file, zenoh_error_text, Error, Keys, Subscriber,
    SubscriberStats, PLACEHOLDER_PASSWORD,
};
