//! Couplings between a world's stages: what joins models that cannot step side by side.
//!
//! A world's models are put in stages. The models of one stage step in parallel; the stages
//! step one after another. Before each stage (and before each of its substeps, where it takes
//! several), the caller's [`Couplings`] run with mutable access to every model, typed: with
//! `World<M>` and `M` an enum of the procedure's model types, a coupling matches on the
//! variants it joins. Once more after the last stage, for what gathers the step's results.

use super::world::Slot;
use super::{EventKind, ModelId, TissueModel};

/// Where in a step a coupling runs: before substep `substep` of `substeps` of stage `stage`,
/// or, with `stage` equal to the world's stage count, after the last stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Phase {
    pub stage: u32,
    pub substep: u32,
    pub substeps: u32,
}

impl Phase {
    /// Whether this is the first substep of its stage (where once-a-step work goes).
    pub fn first(&self) -> bool {
        self.substep == 0
    }
}

/// What a procedure runs between its world's stages. It owns its own state (scratch,
/// tool inputs, what a step did) and reads it back after the step, typed.
pub trait Couplings<M> {
    fn couple(
        &mut self,
        phase: Phase,
        dt_s: f32,
        models: &mut Models<'_, M>,
        events: &mut Vec<EventKind>,
    );
}

/// No couplings: a world whose models only meet through interactions.
pub struct Uncoupled;

impl<M> Couplings<M> for Uncoupled {
    fn couple(&mut self, _: Phase, _: f32, _: &mut Models<'_, M>, _: &mut Vec<EventKind>) {}
}

/// The models as a coupling sees them: all can be read; only those not quarantined written.
pub struct Models<'a, M> {
    pub(super) slots: &'a mut [Slot<M>],
}

impl<M: TissueModel> Models<'_, M> {
    /// Model `id` (frozen or not: a quarantined model holds its last good state).
    pub fn get(&self, id: ModelId) -> Option<&M> {
        self.slots.get(id.index()).map(|s| &s.model)
    }

    /// Model `id` to write, unless it was quarantined (it no longer changes).
    pub fn get_mut(&mut self, id: ModelId) -> Option<&mut M> {
        self.slots
            .get_mut(id.index())
            .filter(|s| !s.guard.is_frozen())
            .map(|s| &mut s.model)
    }

    /// Two different models, the first to write (unless quarantined), the second to read.
    pub fn write_read(&mut self, write: ModelId, read: ModelId) -> (Option<&mut M>, Option<&M>) {
        let (w, r) = (write.index(), read.index());
        if w == r || w >= self.slots.len() || r >= self.slots.len() {
            return (None, None);
        }
        let (a, b) = if w < r {
            let (lo, hi) = self.slots.split_at_mut(r);
            (&mut lo[w], &hi[0])
        } else {
            let (lo, hi) = self.slots.split_at_mut(w);
            (&mut hi[0], &lo[r])
        };
        let a = (!a.guard.is_frozen()).then_some(&mut a.model);
        (a, Some(&b.model))
    }

    /// Two different models to write (each `None` when quarantined).
    pub fn pair_mut(&mut self, a: ModelId, b: ModelId) -> (Option<&mut M>, Option<&mut M>) {
        let (i, j) = (a.index(), b.index());
        if i == j || i >= self.slots.len() || j >= self.slots.len() {
            return (None, None);
        }
        let (x, y) = if i < j {
            let (lo, hi) = self.slots.split_at_mut(j);
            (&mut lo[i], &mut hi[0])
        } else {
            let (lo, hi) = self.slots.split_at_mut(i);
            (&mut hi[0], &mut lo[j])
        };
        (
            (!x.guard.is_frozen()).then_some(&mut x.model),
            (!y.guard.is_frozen()).then_some(&mut y.model),
        )
    }
}
