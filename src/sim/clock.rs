use std::time::{Duration, Instant};

/// How the clock relates simulated time to the wall clock.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Pacing {
    /// Step as fast as possible (headless, replay, benchmarks).
    #[default]
    AsFastAsPossible,
    /// Sleep so that simulated time never runs ahead of the wall clock (interactive sessions).
    RealTime,
}

/// A fixed-step clock. Time is kept as an integer step count so that it never drifts.
#[derive(Debug, Clone)]
pub struct Clock {
    dt_s: f32,
    step: u64,
    pacing: Pacing,
    start: Option<Instant>,
}

impl Clock {
    pub fn new(dt_s: f32, pacing: Pacing) -> Self {
        Self {
            dt_s,
            step: 0,
            pacing,
            start: None,
        }
    }

    pub fn dt_s(&self) -> f32 {
        self.dt_s
    }

    pub fn step(&self) -> u64 {
        self.step
    }

    /// Simulated time at the current step, seconds (computed in f64 from the step count).
    pub fn time_s(&self) -> f64 {
        self.step as f64 * self.dt_s as f64
    }

    /// After a pause: real-time pacing goes on from now (it does not race to catch up the
    /// wall time spent paused).
    pub fn resume(&mut self) {
        if self.start.is_some() {
            self.start = Instant::now().checked_sub(Duration::from_secs_f64(self.time_s()));
        }
    }

    /// From now on, real-time pacing with the current step at the wall clock's now (a
    /// session warmed up as fast as possible and then run live).
    pub fn pace_from_now(&mut self) {
        self.pacing = Pacing::RealTime;
        self.start.get_or_insert_with(Instant::now);
        self.resume();
    }

    /// How far simulated time is ahead of the wall clock since the first real-time tick,
    /// seconds (negative: behind); none before it or when stepping as fast as possible.
    pub fn lead_s(&self) -> Option<f64> {
        let start = self.start.filter(|_| self.pacing == Pacing::RealTime)?;
        Some(self.time_s() - start.elapsed().as_secs_f64())
    }

    /// Advances one step; in real-time mode waits until the wall clock has caught up.
    pub fn tick(&mut self) {
        self.step += 1;
        if self.pacing == Pacing::RealTime {
            let start = *self.start.get_or_insert_with(Instant::now);
            let due = Duration::from_secs_f64(self.time_s());
            let elapsed = start.elapsed();
            if due > elapsed {
                std::thread::sleep(due - elapsed);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_is_exact_multiple_of_dt() {
        let mut c = Clock::new(0.002, Pacing::AsFastAsPossible);
        for _ in 0..1_000_000 {
            c.tick();
        }
        assert_eq!(c.step(), 1_000_000);
        // No accumulated rounding: exactly steps x dt.
        assert_eq!(c.time_s(), 1_000_000.0 * f64::from(0.002f32));
    }

    #[test]
    fn real_time_pacing_never_runs_ahead_of_the_wall_clock() {
        let mut c = Clock::new(0.001, Pacing::RealTime);
        assert_eq!(c.lead_s(), None, "no wall clock before the first tick");
        // After every tick, the simulated time is not ahead of the wall time since the first
        // (the sleep's lower bound: behaviour, not speed).
        for _ in 0..20 {
            c.tick();
            let lead = c.lead_s().expect("started");
            assert!(lead <= 0.0, "{lead} s ahead at step {}", c.step());
        }
        // A pause of 50 ms leaves the clock at least that far behind; resuming goes on from
        // the wall clock's now instead of racing to catch up.
        std::thread::sleep(Duration::from_millis(50));
        let paused = c.lead_s().expect("started");
        assert!(paused <= -0.05, "{paused}");
        c.resume();
        let lead = c.lead_s().expect("started");
        assert!(lead <= 0.0 && lead > paused, "{paused} -> {lead}");
        // A clock stepped as fast as possible to 1 s and then paced from now does not wait
        // that second out: it stands at the wall clock's now.
        let mut warm = Clock::new(0.001, Pacing::AsFastAsPossible);
        for _ in 0..1000 {
            warm.tick();
        }
        warm.pace_from_now();
        let lead = warm.lead_s().expect("paced");
        assert!(lead <= 0.0 && lead > -0.5, "{lead}");
        // As fast as possible: no wall clock is kept at all.
        let mut fast = Clock::new(1.0, Pacing::AsFastAsPossible);
        fast.tick();
        assert_eq!((fast.lead_s(), fast.time_s()), (None, 1.0));
    }
}
