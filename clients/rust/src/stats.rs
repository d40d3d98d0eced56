//! Per-stream accounting: sequence gaps and latency, with the rules of the Python
//! client (`gyrotherm.client._stats`, docs/wire-format.md "Client semantics").
//!
//! * [`SequenceTracker`] from `seq` (uint64, 0 first): `seq == last + 1` in order;
//!   `seq > last + 1` one *gap* of `seq − last − 1` *missing* messages;
//!   `seq == last` a *duplicate*; `seq < last` a *reset* (the publisher restarted; if
//!   the first seq of the new run is `s > 0`, its `s` predecessors count as one more
//!   gap). The first message seen is never a gap (a late join is not a loss).
//! * [`LatencyTracker`] (s): count, mean, min and max exact; p50/p99 nearest-rank
//!   percentiles of a uniform reservoir (algorithm R) of at most `reservoir_size`
//!   latencies, exact while `count <= reservoir_size`. Beyond that the sample differs
//!   from Python's (another seeded generator: SplitMix64 here, Mersenne Twister there)
//!   but has the same distribution.

/// Latency summary in seconds; NaN fields while `count == 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatencyStats {
    pub count: u64,
    pub mean_s: f64,
    pub min_s: f64,
    pub max_s: f64,
    pub p50_s: f64,
    pub p99_s: f64,
}

/// Nearest-rank percentile: `sorted[ceil(pct/100·n) − 1]`; NaN when empty.
pub fn percentile(sorted_values: &[f64], pct: f64) -> f64 {
    let n = sorted_values.len();
    if n == 0 {
        return f64::NAN;
    }
    let rank = ((pct / 100.0 * n as f64).ceil() as usize).max(1);
    sorted_values[rank.min(n) - 1]
}

/// Running latency statistics with a bounded reservoir for the percentiles.
#[derive(Debug, Clone)]
pub struct LatencyTracker {
    size: usize,
    rng: u64,
    reservoir: Vec<f64>,
    count: u64,
    sum: f64,
    min: f64,
    max: f64,
}

impl LatencyTracker {
    /// `reservoir_size` ≥ 1 (the Python client's default is 4096); `seed` fixes the
    /// reservoir's choices.
    pub fn new(reservoir_size: usize, seed: u64) -> Result<Self, String> {
        if reservoir_size < 1 {
            return Err(format!(
                "reservoir_size = {reservoir_size} is invalid: must be >= 1"
            ));
        }
        Ok(Self {
            size: reservoir_size,
            rng: seed,
            reservoir: Vec::new(),
            count: 0,
            sum: 0.0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
        })
    }

    fn next_u64(&mut self) -> u64 {
        // SplitMix64
        self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Record one latency (s).
    pub fn add(&mut self, latency_s: f64) {
        self.count += 1;
        self.sum += latency_s;
        self.min = self.min.min(latency_s);
        self.max = self.max.max(latency_s);
        if self.reservoir.len() < self.size {
            self.reservoir.push(latency_s);
        } else {
            // uniform j in [0, count): Lemire's multiply-shift (bias < 2^-64·count)
            let j = ((u128::from(self.next_u64()) * u128::from(self.count)) >> 64) as u64;
            if (j as usize) < self.size {
                self.reservoir[j as usize] = latency_s;
            }
        }
    }

    /// Current statistics.
    pub fn snapshot(&self) -> LatencyStats {
        if self.count == 0 {
            let nan = f64::NAN;
            return LatencyStats {
                count: 0,
                mean_s: nan,
                min_s: nan,
                max_s: nan,
                p50_s: nan,
                p99_s: nan,
            };
        }
        let mut ordered = self.reservoir.clone();
        ordered.sort_by(f64::total_cmp);
        LatencyStats {
            count: self.count,
            mean_s: self.sum / self.count as f64,
            min_s: self.min,
            max_s: self.max,
            p50_s: percentile(&ordered, 50.0),
            p99_s: percentile(&ordered, 99.0),
        }
    }
}

impl Default for LatencyTracker {
    fn default() -> Self {
        Self::new(4096, 0).expect("4096 >= 1")
    }
}

/// Gap / reset accounting of one stream's `seq` (rules in the module docs).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SequenceTracker {
    pub last_seq: Option<u64>,
    pub gaps: u64,
    pub missing: u64,
    pub resets: u64,
    pub duplicates: u64,
}

impl SequenceTracker {
    pub fn new() -> Self {
        Self::default()
    }

    /// Account for the next received `seq`.
    pub fn observe(&mut self, seq: u64) {
        if let Some(last) = self.last_seq {
            if seq > last && seq - last > 1 {
                self.gaps += 1;
                self.missing += seq - last - 1;
            } else if seq == last {
                self.duplicates += 1;
                return;
            } else if seq < last {
                self.resets += 1;
                if seq > 0 {
                    self.gaps += 1;
                    self.missing += seq;
                }
            }
        }
        self.last_seq = Some(seq);
    }
}

/// Counters of one stream since the subscriber opened.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamStats {
    pub received: u64,
    pub gaps: u64,
    pub missing: u64,
    pub resets: u64,
    pub duplicates: u64,
    pub undecodable: u64,
    /// Messages the bounded queue dropped (oldest first).
    pub dropped: u64,
    pub last_seq: Option<u64>,
    pub last_error: Option<String>,
    pub latency: LatencyStats,
    /// Messages delivered with `NON_FINITE`.
    pub non_finite: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(seqs: &[u64]) -> SequenceTracker {
        let mut t = SequenceTracker::new();
        for &s in seqs {
            t.observe(s);
        }
        t
    }

    #[test]
    fn in_order_and_late_join_are_not_gaps() {
        let t = run(&[5, 6, 7, 8]);
        assert_eq!(
            (t.gaps, t.missing, t.resets, t.duplicates, t.last_seq),
            (0, 0, 0, 0, Some(8))
        );
    }

    #[test]
    fn gaps_count_missing() {
        // 0 1 [2 3] 4 [5] 6 7 [8..9] 10: three gaps, 2 + 1 + 2 missing
        let t = run(&[0, 1, 4, 6, 7, 10]);
        assert_eq!((t.gaps, t.missing), (3, 5));
    }

    #[test]
    fn duplicate_and_resets() {
        // 3 3: duplicate; 9 → 0: reset, no gap; 0 1 → 4: gap of 2; 4 → 2: reset whose
        // 2 predecessors (0, 1) count as one more gap
        let t = run(&[3, 3, 4, 9, 0, 1, 4, 2, 3]);
        assert_eq!(t.duplicates, 1);
        assert_eq!(t.resets, 2);
        assert_eq!((t.gaps, t.missing), (1 + 1 + 1, 4 + 2 + 2));
        assert_eq!(t.last_seq, Some(3));
    }

    #[test]
    fn seq_near_u64_max_does_not_overflow() {
        let t = run(&[u64::MAX - 2, u64::MAX]);
        assert_eq!((t.gaps, t.missing), (1, 1));
    }

    #[test]
    fn percentile_nearest_rank() {
        let v: Vec<f64> = (1..=10).map(f64::from).collect();
        assert_eq!(percentile(&v, 50.0), 5.0);
        assert_eq!(percentile(&v, 99.0), 10.0);
        assert_eq!(percentile(&v, 0.0), 1.0);
        assert_eq!(percentile(&[2.5], 99.0), 2.5);
        assert!(percentile(&[], 50.0).is_nan());
    }

    #[test]
    fn latency_exact_within_reservoir() {
        let mut t = LatencyTracker::new(4096, 0).unwrap();
        assert!(t.snapshot().p50_s.is_nan());
        // 0.001 … 0.200 s, shuffled: p50 = 100th smallest, p99 = 198th
        let mut v: Vec<f64> = (1..=200).map(|k| f64::from(k) / 1000.0).collect();
        v.reverse();
        v.swap(3, 150);
        for &x in &v {
            t.add(x);
        }
        let s = t.snapshot();
        assert_eq!(s.count, 200);
        assert_eq!(s.p50_s, 0.100);
        assert_eq!(s.p99_s, 0.198);
        assert_eq!((s.min_s, s.max_s), (0.001, 0.200));
        assert!((s.mean_s - 0.1005).abs() < 1e-12);
    }

    #[test]
    fn reservoir_stays_bounded_and_uniform() {
        let mut t = LatencyTracker::new(1000, 1).unwrap();
        for k in 0..100_000 {
            t.add(f64::from(k));
        }
        let s = t.snapshot();
        assert_eq!(t.reservoir.len(), 1000);
        assert_eq!((s.count, s.min_s, s.max_s), (100_000, 0.0, 99_999.0));
        // uniform over 0 … 99 999: p50 ≈ 50 000 (σ of the median of 1000 ≈ 1 600)
        assert!((s.p50_s - 50_000.0).abs() < 6_000.0, "p50 {}", s.p50_s);
        assert!(s.p99_s > 95_000.0, "p99 {}", s.p99_s);
        assert!(LatencyTracker::new(0, 0).is_err());
    }
}
