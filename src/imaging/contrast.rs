//! Contrast medium in a vessel tree: a puff injected at a point of a vessel is carried with the
//! blood (plug flow, velocity `Q / (pi r^2)` in each vessel), fills the vessels downstream of
//! it and washes out when the injection stops. Transport is exact advection: the
//! concentration at distance `s` along a vessel at time `t` is what entered the vessel (or
//! was injected at `s0 <= s`) `s / v` (or `(s - s0) / v`) earlier, read from each vessel's
//! history by linear interpolation, so it does not depend on the step. A puff of rate `q` into
//! a vessel carrying `Q` has the concentration `q / (Q + q)` (undiluted contrast is 1); the
//! vessel's velocity is taken as its blood's alone. Branches take their parent's outflow.

use std::fmt;

/// One vessel: its parent (none: the tree's root, fed by clean blood), length, radius and the
/// blood flow through it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vessel {
    pub parent: Option<usize>,
    pub length_m: f64,
    pub radius_m: f64,
    pub flow_m3_per_s: f64,
}

impl Vessel {
    pub fn velocity_m_per_s(&self) -> f64 {
        self.flow_m3_per_s / (std::f64::consts::PI * self.radius_m * self.radius_m)
    }
}

/// Why a tree was refused (the vessel's index and what is wrong).
#[derive(Debug, Clone, PartialEq)]
pub struct TreeError {
    pub vessel: usize,
    pub message: String,
}

impl fmt::Display for TreeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "vessel[{}]: {}", self.vessel, self.message)
    }
}

impl std::error::Error for TreeError {}

/// The tree and the contrast in it.
#[derive(Debug, Clone)]
pub struct Contrast {
    vessels: Vec<Vessel>,
    dt_s: f64,
    /// Steps taken.
    steps: usize,
    /// The step the histories start at (older values, past every vessel's transit, are
    /// dropped), and how many a history keeps at least.
    base: usize,
    window: usize,
    /// What entered each vessel at its start, a value a step.
    entered: Vec<Vec<f64>>,
    /// What was injected into each vessel a step, and where (the point of its latest puff).
    injected: Vec<Vec<f64>>,
    at_m: Vec<f64>,
}

impl Contrast {
    /// A tree stepped every `dt_s`: each vessel's parent comes before it, every length,
    /// radius and flow is positive and finite, and a vessel's children carry its flow between
    /// them (within 0.1 %).
    pub fn new(vessels: Vec<Vessel>, dt_s: f64) -> Result<Contrast, TreeError> {
        let bad = |vessel, message: String| Err(TreeError { vessel, message });
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return bad(0, format!("the step must be a positive time, not {dt_s}"));
        }
        for (k, v) in vessels.iter().enumerate() {
            for (name, x) in [
                ("length_m", v.length_m),
                ("radius_m", v.radius_m),
                ("flow_m3_per_s", v.flow_m3_per_s),
            ] {
                if !(x.is_finite() && x > 0.0) {
                    return bad(k, format!("'{name}' must be a positive number, not {x}"));
                }
            }
            if v.parent.is_some_and(|p| p >= k) {
                return bad(k, "its parent must be listed before it".into());
            }
        }
        for (k, v) in vessels.iter().enumerate() {
            let children: f64 = vessels
                .iter()
                .filter(|c| c.parent == Some(k))
                .map(|c| c.flow_m3_per_s)
                .sum();
            if children > 0.0 && (children - v.flow_m3_per_s).abs() > 1e-3 * v.flow_m3_per_s {
                return bad(
                    k,
                    format!(
                        "its branches carry {children:e} m^3/s, it carries {:e}: blood is \
                         neither made nor lost at a branching",
                        v.flow_m3_per_s
                    ),
                );
            }
        }
        let n = vessels.len();
        let window = vessels
            .iter()
            .map(|v| (v.length_m / (v.velocity_m_per_s() * dt_s)).ceil() as usize)
            .max()
            .unwrap_or(0)
            + 2;
        Ok(Contrast {
            vessels,
            dt_s,
            steps: 0,
            base: 0,
            window,
            entered: vec![Vec::new(); n],
            injected: vec![Vec::new(); n],
            at_m: vec![0.0; n],
        })
    }

    pub fn vessels(&self) -> &[Vessel] {
        &self.vessels
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * self.dt_s
    }

    /// The value of `history` (which starts at step `base`) at step `now`, linearly between
    /// steps (0 before the session began).
    fn back(history: &[f64], base: usize, now: f64) -> f64 {
        let now = now - base as f64;
        if now < 0.0 || history.is_empty() {
            return 0.0;
        }
        let i = now.floor() as usize;
        let f = now - now.floor();
        let at = |i: usize| history.get(i).copied().unwrap_or(0.0);
        at(i) * (1.0 - f) + at(i + 1) * f
    }

    /// The concentration in vessel `k` at `s` metres from its start, now.
    pub fn concentration(&self, k: usize, s: f64) -> f64 {
        self.at_step(k, s, self.steps as f64 - 1.0)
    }

    fn at_step(&self, k: usize, s: f64, step: f64) -> f64 {
        let Some(v) = self.vessels.get(k) else {
            return 0.0;
        };
        let per_step = v.velocity_m_per_s() * self.dt_s;
        let s = s.clamp(0.0, v.length_m);
        let upstream = Self::back(&self.entered[k], self.base, step - s / per_step);
        let puff = if s >= self.at_m[k] {
            Self::back(
                &self.injected[k],
                self.base,
                step - (s - self.at_m[k]) / per_step,
            )
        } else {
            0.0
        };
        1.0 - (1.0 - upstream) * (1.0 - puff)
    }

    /// One step, with a puff of `rate_m3_per_s` into vessel `k` at `s` metres from its start
    /// (none: no injection).
    pub fn step(&mut self, puff: Option<(usize, f64, f64)>) {
        let now = self.steps as f64;
        for k in 0..self.vessels.len() {
            let entering = match self.vessels[k].parent {
                None => 0.0,
                Some(p) => self.at_step(p, self.vessels[p].length_m, now),
            };
            self.entered[k].push(entering);
            let c = match puff {
                Some((j, s, rate)) if j == k && rate > 0.0 && rate.is_finite() => {
                    let last = self.injected[k].last().copied().unwrap_or(0.0);
                    if last == 0.0 {
                        // A new puff: from where the catheter's tip is now.
                        self.at_m[k] = s.clamp(0.0, self.vessels[k].length_m);
                    }
                    rate / (self.vessels[k].flow_m3_per_s + rate)
                }
                _ => 0.0,
            };
            self.injected[k].push(c);
        }
        self.steps += 1;
        // Drop what no vessel reads any more (older than the longest transit).
        let kept = self.steps - self.base;
        if kept > 2 * self.window {
            let drop = kept - self.window;
            for h in self.entered.iter_mut().chain(self.injected.iter_mut()) {
                h.drain(..drop);
            }
            self.base += drop;
        }
    }
}

#[cfg(test)]
#[path = "contrast_tests.rs"]
mod tests;
