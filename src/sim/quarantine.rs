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

    /// Call after the model stepped. Returns an event when the model was quarantined.
    pub fn after_step(&mut self, model: &mut dyn TissueModel, step: u64) -> Option<EventKind> {
        if self.frozen {
            return None;
        }
        if !model.state_is_finite() {
            model.restore();
            self.frozen = true;
            return Some(EventKind::Quarantined {
                model: model.name().to_string(),
                restored_step: self.last_good_step,
            });
        }
        if step.is_multiple_of(self.interval) {
            model.checkpoint();
            self.last_good_step = step;
        }
        None
    }
}
