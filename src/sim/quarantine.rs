use super::{EventKind, TissueModel};

/// Guards one model: checkpoints every `interval` steps, and when the model's state goes
/// non-finite rolls it back to the last good checkpoint and freezes it.
#[derive(Debug, Clone)]
pub struct Quarantine {
    interval: u64,
    last_good_step: u64,
    frozen: bool,
}

impl Quarantine {
    pub fn new(interval: u64) -> Self {
        Self {
            interval: interval.max(1),
            last_good_step: 0,
            frozen: false,
        }
    }

    pub fn is_frozen(&self) -> bool {
        self.frozen
    }

    /// Whether a checkpoint is taken after step `step` (if its state is finite).
    pub fn checkpoint_due(&self, step: u64) -> bool {
        !self.frozen && step.is_multiple_of(self.interval)
    }

    /// Call after the model stepped. Returns an event when the model was quarantined.
    pub fn after_step(&mut self, model: &mut dyn TissueModel, step: u64) -> Option<EventKind> {
        if self.frozen {
            return None;
        }
        if let Some(e) = self.check(model) {
            return Some(e);
        }
        if step.is_multiple_of(self.interval) {
            model.checkpoint();
            self.last_good_step = step;
        }
        None
    }

    /// Call after a substep that is not the step's last: the state is checked (a coupling
    /// must not read a NaN before the step ends) but no checkpoint is taken, so a rollback
    /// always returns to the end of a whole step.
    pub fn check(&mut self, model: &mut dyn TissueModel) -> Option<EventKind> {
        if self.frozen || model.state_is_finite() {
            return None;
        }
        model.restore();
        self.frozen = true;
        Some(EventKind::Quarantined {
            model: model.name().to_string(),
            restored_step: self.last_good_step,
        })
    }
}
