//! Emissions: things the simulation gives off at an instant (smoke where an energized
//! instrument cuts) that the renderer animates by itself from the snapshot's time, and the
//! bounded log a procedure keeps of them.

use glam::Vec3;
use std::collections::VecDeque;

/// What an emission puts into the scene.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum EmissionKind {
    /// Surgical smoke: vaporized tissue rising from where the current cut.
    #[default]
    Smoke,
}

/// One emission: when and where it began. The renderer draws it as a pure function of the
/// snapshot's time minus `time_s` and of `time_s` itself (its seed), so the same snapshot
/// gives the same pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Emission {
    /// Simulation time of the end of the step that gave it off, s.
    pub time_s: f64,
    /// Where it began (the working end of the instrument), m.
    pub position: Vec3,
    pub kind: EmissionKind,
}

/// The recent emissions of one source: at most one every `interval_s`, none older than
/// `window_s`, at most `cap` (the snapshot carries them all, so they must stay few).
#[derive(Debug, Clone)]
pub struct EmissionLog {
    interval_s: f64,
    window_s: f64,
    cap: usize,
    recent: VecDeque<Emission>,
}

impl EmissionLog {
    /// Smoke's log: one emission every 15 ms while cutting (6 or 7 per 100 ms, so a sweep of
    /// the hook leaves a trail, not one puff per millisecond step), kept 2 s (past the
    /// renderer's 1.5 s lifetime of a puff), at most 160 (2 s at 15 ms is 134).
    pub fn smoke() -> Self {
        Self::new(0.015, 2.0, 160)
    }

    pub fn new(interval_s: f64, window_s: f64, cap: usize) -> Self {
        EmissionLog {
            interval_s,
            window_s,
            cap,
            recent: VecDeque::with_capacity(cap.min(256)),
        }
    }

    /// Records an emission at `time_s` unless the last one is under `interval_s` older;
    /// returns whether it was recorded. Drops what falls out of the window or past the cap.
    pub fn record(&mut self, time_s: f64, position: Vec3, kind: EmissionKind) -> bool {
        let due = self
            .recent
            .back()
            .is_none_or(|last| time_s - last.time_s >= self.interval_s);
        if due {
            self.recent.push_back(Emission {
                time_s,
                position,
                kind,
            });
        }
        self.forget_before(time_s);
        due
    }

    /// Drops emissions older than the window at `now_s`, and the oldest past the cap.
    pub fn forget_before(&mut self, now_s: f64) {
        while self
            .recent
            .front()
            .is_some_and(|e| now_s - e.time_s > self.window_s)
        {
            self.recent.pop_front();
        }
        while self.recent.len() > self.cap {
            self.recent.pop_front();
        }
    }

    /// The emissions within the window at `now_s` and not after it, oldest first.
    pub fn at(&self, now_s: f64) -> Vec<Emission> {
        self.recent
            .iter()
            .filter(|e| e.time_s <= now_s && now_s - e.time_s <= self.window_s)
            .copied()
            .collect()
    }

    pub fn len(&self) -> usize {
        self.recent.len()
    }

    pub fn is_empty(&self) -> bool {
        self.recent.is_empty()
    }
}

/// A bleeding source: where blood wells up (a cut vessel, an injury), since when, and when it
/// was stopped (a clip, coagulation), if it was. The renderer draws its pool and drops as a
/// pure function of these and the snapshot's time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bleed {
    pub position: Vec3,
    pub start_s: f64,
    pub stop_s: Option<f64>,
}

impl Bleed {
    /// Seconds it has bled by `now_s` (none before it began; it stops counting when stopped).
    pub fn bled_s(&self, now_s: f64) -> f64 {
        let end = self.stop_s.map_or(now_s, |s| s.min(now_s));
        (end - self.start_s).max(0.0)
    }

    /// Whether it still bleeds at `now_s`.
    pub fn active(&self, now_s: f64) -> bool {
        now_s >= self.start_s && self.stop_s.is_none_or(|s| now_s < s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_thins_to_its_interval_and_forgets_past_its_window_and_cap() {
        let mut log = EmissionLog::new(0.015, 2.0, 5);
        let p = Vec3::new(0.01, 0.02, 0.03);
        // Every millisecond for 50 ms: one at 0, 15, 30 and 45 ms.
        let kept: Vec<bool> = (0..50)
            .map(|k| log.record(k as f64 * 0.001, p, EmissionKind::Smoke))
            .collect();
        assert_eq!(kept.iter().filter(|&&k| k).count(), 4);
        assert!(kept[0] && kept[15] && kept[30] && kept[45] && !kept[14]);
        assert_eq!(log.at(0.05).len(), 4);
        // Not yet given off at 20 ms: only two of them show in a snapshot then.
        assert_eq!(log.at(0.02).len(), 2);
        // The cap keeps the newest.
        for k in 0..4 {
            log.record(0.1 + k as f64 * 0.02, p, EmissionKind::Smoke);
        }
        assert_eq!(log.len(), 5);
        assert_eq!(log.at(1.0)[0].time_s, 0.045);
        // Past the window they are gone.
        log.forget_before(2.15);
        assert_eq!(log.len(), 1);
        assert_eq!(log.at(2.15)[0].time_s, 0.16);
        log.forget_before(10.0);
        assert!(log.is_empty());
    }
}
