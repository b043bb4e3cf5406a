//! Motion analysis of the instruments, the same for every procedure: how far each instrument
//! tip travelled, in how many movements, how directly between the places it worked, how
//! smoothly, how long it stood idle, how fast it moved, and how the two hands moved together.
//! These are the measures of the motion-analysis literature (the Imperial College Surgical
//! Assessment Device's path length, number of movements and time; economy of motion and idle
//! time as the commercial laparoscopy trainers report them; the log dimensionless jerk of
//! Balasubramanian et al. for smoothness); the README's "Motion analysis" defines each.
//!
//! The session samples both tips at a fixed rate of simulated time ([`SAMPLE_HZ`]), so a
//! measure does not change with the scenario's step, and notes where each instrument began to
//! act (a button pressed). Everything is computed from those samples at the end.

use glam::Vec3;
use serde::Serialize;

/// Tip samples per simulated second.
pub const SAMPLE_HZ: f64 = 50.0;
/// Samples of the centred moving average that smooths the positions for the speed profile,
/// applied twice (a triangular window of 0.42 s: a hand tremor of 4-12 Hz keeps less than
/// 5 % of its amplitude, a reach of 1 Hz 85 %).
pub const SMOOTHING_SAMPLES: usize = 11;
/// A movement starts where the smoothed speed rises above this, m/s...
pub const MOVE_ON_M_PER_S: f64 = 0.01;
/// ...and ends where it falls below this, m/s.
pub const MOVE_OFF_M_PER_S: f64 = 0.005;
/// Shorter stretches above the threshold are not movements, s.
pub const MIN_MOVEMENT_S: f64 = 0.1;
/// A tip that moves less than this between two samples stands still (the ends of a movement
/// where it does are not part of its duration), m.
pub const STILL_M: f64 = 1e-7;
/// An instrument works in a session when its tip's smoothed path (its tremor left out) is this
/// long or it acts, m.
pub const WORKING_PATH_M: f64 = 0.02;

/// One instrument's samples.
#[derive(Debug, Clone, Default)]
struct Track {
    samples: Vec<Vec3>,
    /// The tip where the instrument began to act, each time.
    actions: Vec<Vec3>,
    acting: bool,
}

/// Collects both tips during a session (call [`MotionRecorder::record`] after every step).
#[derive(Debug, Clone, Default)]
pub struct MotionRecorder {
    tracks: [Track; 2],
    /// Samples taken so far (the next is due at `taken / SAMPLE_HZ` seconds).
    taken: u64,
}

impl MotionRecorder {
    pub fn new() -> Self {
        Self::default()
    }

    /// The tips after the step that ended at `time_s`, and whether each instrument acts.
    /// Non-finite tips are taken as the last finite sample.
    pub fn record(&mut self, time_s: f64, tips: [Vec3; 2], acting: [bool; 2]) {
        for (k, t) in self.tracks.iter_mut().enumerate() {
            let tip = if tips[k].is_finite() {
                tips[k]
            } else {
                t.samples.last().copied().unwrap_or(Vec3::ZERO)
            };
            if acting[k] && !t.acting {
                t.actions.push(tip);
            }
            t.acting = acting[k];
        }
        // A sample at every multiple of the period this step reached (a step longer than the
        // period repeats its tips).
        while self.taken as f64 / SAMPLE_HZ <= time_s + 1e-9 {
            for (k, t) in self.tracks.iter_mut().enumerate() {
                let tip = if tips[k].is_finite() {
                    tips[k]
                } else {
                    t.samples.last().copied().unwrap_or(Vec3::ZERO)
                };
                t.samples.push(tip);
            }
            self.taken += 1;
        }
    }

    /// Samples taken so far.
    pub fn samples(&self) -> u64 {
        self.taken
    }

    /// The measures of the session so far.
    pub fn analyse(&self) -> Motion {
        let hands = [0, 1].map(|k| {
            let t = &self.tracks[k];
            analyse_hand(&t.samples, &t.actions)
        });
        let speeds = [0, 1].map(|k| smoothed_speed(&self.tracks[k].samples));
        combine(&hands, &speeds, self.taken)
    }
}

/// One instrument's measures.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HandMotion {
    pub path_m: f64,
    pub movements: u32,
    /// The straight distances from the start through each place it began to act to the end,
    /// and their sum.
    pub straight_m: f64,
    pub acted: bool,
    /// The path of the smoothed positions (without the tremor), m.
    pub smooth_path_m: f64,
    /// Each movement's log dimensionless jerk and duration, s.
    pub ldlj: Vec<(f64, f64)>,
    /// Time in movements, and the path travelled in them.
    pub moving_s: f64,
    pub moving_path_m: f64,
    /// Sampled time, s.
    pub duration_s: f64,
}

impl HandMotion {
    pub fn working(&self) -> bool {
        self.acted || self.smooth_path_m >= WORKING_PATH_M
    }
}

/// A session's motion measures (the report's `motion`, the measures `motion.<key>`): both
/// instruments together where they work, and each one's path.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Motion {
    /// Simulated time sampled, s.
    pub duration_s: f64,
    /// Instruments that worked (travelled 2 cm or acted).
    pub instruments: u32,
    /// Path length of both tips, m, and of each.
    pub path_m: f64,
    pub left_path_m: f64,
    pub right_path_m: f64,
    /// Movements of the working instruments, in all.
    pub movements: u32,
    /// The straight distances between the places the instruments worked over their paths
    /// (1: no detour); none where no instrument acted.
    pub economy: Option<f64>,
    /// The movements' log dimensionless jerk, weighted by their durations (nearer 0:
    /// smoother); none without movements.
    pub ldlj: Option<f64>,
    /// Time no working instrument was in a movement, s.
    pub idle_s: f64,
    /// Mean tip speed in movements, m/s; none without movements.
    pub speed_m_per_s: Option<f64>,
    /// The correlation of the two tips' smoothed speeds (1: the hands move together); none
    /// unless both work.
    pub bimanual: Option<f64>,
}

impl Motion {
    /// The measure names a tree may bind, with the session's values (`motion.<key>`).
    pub fn measures(&self) -> Vec<(String, Option<f64>)> {
        let v = serde_json::to_value(self).unwrap_or_default();
        let mut out = Vec::new();
        if let Some(o) = v.as_object() {
            for (k, x) in o {
                out.push((format!("motion.{k}"), x.as_f64().filter(|x| x.is_finite())));
            }
        }
        out
    }
}

/// Positions smoothed by the centred moving average twice (shorter at the ends).
pub fn smoothed(samples: &[Vec3]) -> Vec<Vec3> {
    average(&average(samples))
}

fn average(samples: &[Vec3]) -> Vec<Vec3> {
    let half = SMOOTHING_SAMPLES / 2;
    let last = samples.len().saturating_sub(1);
    (0..samples.len())
        .map(|i| {
            // Beyond the ends the first and last samples stand (the tip held there).
            let sum: glam::DVec3 = (i as isize - half as isize..=(i + half) as isize)
                .map(|k| samples[(k.max(0) as usize).min(last)].as_dvec3())
                .sum();
            (sum / SMOOTHING_SAMPLES as f64).as_vec3()
        })
        .collect()
}

/// The smoothed speed between successive samples, m/s (one fewer than the samples).
pub fn smoothed_speed(samples: &[Vec3]) -> Vec<f64> {
    let s = smoothed(samples);
    s.windows(2)
        .map(|w| f64::from(w[1].distance(w[0])) * SAMPLE_HZ)
        .collect()
}

/// The movements in a speed profile: index ranges `[start, end)` of the intervals between
/// samples, by hysteresis between [`MOVE_ON_M_PER_S`] and [`MOVE_OFF_M_PER_S`], at least
/// [`MIN_MOVEMENT_S`] long.
pub fn movements(speed: &[f64]) -> Vec<(usize, usize)> {
    let min_len = (MIN_MOVEMENT_S * SAMPLE_HZ).round() as usize;
    let mut out = Vec::new();
    let mut start: Option<usize> = None;
    for (i, &v) in speed.iter().enumerate() {
        match start {
            None if v > MOVE_ON_M_PER_S => {
                // From where it rose above the lower threshold.
                let mut s = i;
                while s > 0
                    && speed[s - 1] >= MOVE_OFF_M_PER_S
                    && out.last().is_none_or(|&(_, e)| s > e)
                {
                    s -= 1;
                }
                start = Some(s);
            }
            Some(s) if v < MOVE_OFF_M_PER_S => {
                if i - s >= min_len {
                    out.push((s, i));
                }
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start
        && speed.len() - s >= min_len
    {
        out.push((s, speed.len()));
    }
    out
}

/// The log dimensionless jerk of the movement between samples `a` and `b` (b > a): the
/// ends where the tip stands still are left out, then
/// `-ln((t2 - t1)^3 / v_peak^2 * integral |jerk|^2 dt)`, the jerk from third differences
/// (every difference that reaches into the movement), the speed from first differences.
/// Returns it with the movement's duration; none when the tip did not move.
pub fn ldlj(x: &[Vec3], a: usize, b: usize) -> Option<(f64, f64)> {
    let h = 1.0 / SAMPLE_HZ;
    let step = |i: usize| x[i + 1].as_dvec3() - x[i].as_dvec3();
    let moving = |i: usize| step(i).length() > STILL_M;
    let (mut a, mut b) = (a, b.min(x.len().saturating_sub(1)));
    while a < b && !moving(a) {
        a += 1;
    }
    while b > a && !moving(b - 1) {
        b -= 1;
    }
    if b <= a {
        return None;
    }
    let peak = (a..b).map(|i| step(i).length() / h).fold(0.0, f64::max);
    let lo = a.saturating_sub(3);
    let hi = (b + 1).min(x.len().saturating_sub(3));
    let mut jerk2 = 0.0;
    for i in lo..hi {
        let [p0, p1, p2, p3] = [i, i + 1, i + 2, i + 3].map(|k| x[k].as_dvec3());
        let j = (p3 - 3.0 * p2 + 3.0 * p1 - p0) / (h * h * h);
        jerk2 += j.length_squared() * h;
    }
    let duration = (b - a) as f64 * h;
    let dlj = duration.powi(3) / (peak * peak) * jerk2;
    (dlj > 0.0 && dlj.is_finite()).then(|| (-dlj.ln(), duration))
}

/// One instrument's measures from its samples and the places it began to act.
pub fn analyse_hand(samples: &[Vec3], actions: &[Vec3]) -> HandMotion {
    let path_m: f64 = samples
        .windows(2)
        .map(|w| f64::from(w[1].distance(w[0])))
        .sum();
    let speed = smoothed_speed(samples);
    let moves = movements(&speed);
    let mut ldlj_parts = Vec::new();
    let (mut moving_s, mut moving_path_m) = (0.0, 0.0);
    for (k, &(a, b)) in moves.iter().enumerate() {
        moving_s += (b - a) as f64 / SAMPLE_HZ;
        moving_path_m += samples[a..=b.min(samples.len() - 1)]
            .windows(2)
            .map(|w| f64::from(w[1].distance(w[0])))
            .sum::<f64>();
        // Its smoothness over the whole motion: out to where the smoothed speed stops falling
        // (the slow start and end below the thresholds belong to it), not into a neighbour.
        let before = if k == 0 { 0 } else { moves[k - 1].1 };
        let after = moves.get(k + 1).map_or(speed.len(), |m| m.0);
        let (mut s, mut e) = (a, b);
        while s > before && speed[s - 1] <= speed[s] {
            s -= 1;
        }
        while e < after && speed[e] <= speed[e - 1] {
            e += 1;
        }
        if let Some(l) = ldlj(samples, s, e) {
            ldlj_parts.push(l);
        }
    }
    let mut straight_m = 0.0;
    if let (Some(first), Some(last)) = (samples.first(), samples.last()) {
        let mut at = *first;
        for p in actions.iter().chain(std::iter::once(last)) {
            straight_m += f64::from(p.distance(at));
            at = *p;
        }
    }
    HandMotion {
        path_m,
        movements: moves.len() as u32,
        straight_m,
        acted: !actions.is_empty(),
        smooth_path_m: speed.iter().sum::<f64>() / SAMPLE_HZ,
        ldlj: ldlj_parts,
        moving_s,
        moving_path_m,
        duration_s: samples.len().saturating_sub(1) as f64 / SAMPLE_HZ,
    }
}

/// Pearson's correlation of two series (none when either is constant or they are empty).
pub fn correlation(a: &[f64], b: &[f64]) -> Option<f64> {
    let n = a.len().min(b.len());
    if n < 2 {
        return None;
    }
    let (ma, mb) = (
        a[..n].iter().sum::<f64>() / n as f64,
        b[..n].iter().sum::<f64>() / n as f64,
    );
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (da, db) = (a[i] - ma, b[i] - mb);
        sab += da * db;
        saa += da * da;
        sbb += db * db;
    }
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}

/// Both instruments' measures together.
fn combine(hands: &[HandMotion; 2], speeds: &[Vec<f64>; 2], taken: u64) -> Motion {
    let working: Vec<usize> = (0..2).filter(|&k| hands[k].working()).collect();
    let w = |f: &dyn Fn(&HandMotion) -> f64| working.iter().map(|&k| f(&hands[k])).sum::<f64>();
    let acted: Vec<usize> = working
        .iter()
        .copied()
        .filter(|&k| hands[k].acted)
        .collect();
    let acted_path: f64 = acted.iter().map(|&k| hands[k].path_m).sum();
    let acted_straight: f64 = acted.iter().map(|&k| hands[k].straight_m).sum();
    let (mut lsum, mut ltime) = (0.0, 0.0);
    for &k in &working {
        for &(l, d) in &hands[k].ldlj {
            lsum += l * d;
            ltime += d;
        }
    }
    let moving_s = w(&|h| h.moving_s);
    // Idle: intervals in which no working instrument is in a movement.
    let intervals = taken.saturating_sub(1) as usize;
    let mut busy = vec![false; intervals];
    for &k in &working {
        for (a, b) in movements(&speeds[k]) {
            busy[a.min(intervals)..b.min(intervals)].fill(true);
        }
    }
    let idle_s = if working.is_empty() {
        intervals as f64 / SAMPLE_HZ
    } else {
        busy.iter().filter(|b| !**b).count() as f64 / SAMPLE_HZ
    };
    Motion {
        duration_s: intervals as f64 / SAMPLE_HZ,
        instruments: working.len() as u32,
        path_m: hands[0].path_m + hands[1].path_m,
        left_path_m: hands[0].path_m,
        right_path_m: hands[1].path_m,
        movements: working.iter().map(|&k| hands[k].movements).sum(),
        economy: (acted_path > 0.0).then(|| (acted_straight / acted_path).min(1.0)),
        ldlj: (ltime > 0.0).then(|| lsum / ltime),
        idle_s,
        speed_m_per_s: (moving_s > 0.0).then(|| w(&|h| h.moving_path_m) / moving_s),
        bimanual: if working.len() == 2 {
            correlation(&speeds[0], &speeds[1])
        } else {
            None
        },
    }
}

#[cfg(test)]
#[path = "motion_tests.rs"]
mod tests;
