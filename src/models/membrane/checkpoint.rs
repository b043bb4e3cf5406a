//! The membrane's checkpoint (the last good state a rollback returns to), brought up to date
//! by tile. Between two checkpoints only some tiles change: those that stepped (the awake
//! ones), those placed at their anchors (woken, or beside the awake ones where the CPU places
//! them) and those a cut changed. A checkpoint copies those tiles' nodes, and their springs
//! and released marks where a cut changed them, not the whole model: at full size the nodes
//! are 23 MB and the springs 35 MB. Whatever rewrites the model as a whole (a step of every
//! node, a displacement, a layer detached, a value injected) marks everything.

use super::{LAYERS, Membrane, field};

/// What a rollback returns to.
#[derive(Debug, Clone)]
pub(super) struct Saved {
    state: Vec<f32>,
    rows_data: Vec<f32>,
    released: Vec<bool>,
}

/// The tiles whose nodes, or springs and released marks, changed since the last checkpoint.
#[derive(Debug, Clone)]
pub(super) struct Changed {
    /// Everything did (no checkpoint yet, no active set, or the model rewritten as a whole).
    all: bool,
    /// By tile: its nodes' state.
    nodes: Vec<bool>,
    /// By tile: its springs (those that start at its nodes) and released marks.
    springs: Vec<bool>,
    /// The tiles marked in either, to clear them.
    marked: Vec<usize>,
}

impl Changed {
    /// Everything changed: the first checkpoint copies the whole model.
    pub fn everything() -> Changed {
        Changed {
            all: true,
            nodes: Vec::new(),
            springs: Vec::new(),
            marked: Vec::new(),
        }
    }

    fn mark(&mut self, t: usize, springs: bool) {
        if self.all {
            return;
        }
        if self.nodes.len() <= t {
            self.nodes.resize(t + 1, false);
            self.springs.resize(t + 1, false);
        }
        if !self.nodes[t] && !self.springs[t] {
            self.marked.push(t);
        }
        self.nodes[t] = true;
        self.springs[t] |= springs;
    }

    fn clear(&mut self) {
        for &t in &self.marked {
            self.nodes[t] = false;
            self.springs[t] = false;
        }
        self.marked.clear();
        self.all = false;
    }
}

impl Membrane {
    /// Tile `t`'s nodes changed (it stepped, or was placed at its anchors).
    pub(super) fn nodes_changed(&mut self, t: usize) {
        self.changed.mark(t, false);
    }

    /// Tile `t`'s springs or released marks changed (a cut), and with them its nodes.
    pub(super) fn springs_changed_in(&mut self, t: usize) {
        self.changed.mark(t, true);
    }

    /// The model changed as a whole.
    pub(super) fn all_changed(&mut self) {
        self.changed.all = true;
    }

    /// The checkpoint brought up to date: the whole model the first time and after a
    /// whole rewrite, else the tiles that changed since the last one. Where the membrane
    /// steps on a device and a checkpoint was announced, the nodes of the tiles that lag on
    /// the CPU came back into the checkpoint's copy with the step (`device_lazy.rs`): they
    /// are not copied again (nor brought up to date first: [`Membrane::saved_holds_lagging`]).
    pub(super) fn save(&mut self) {
        let whole = self.changed.all || self.activity.is_none();
        let grid = self.tile_grid();
        let slot = std::mem::take(&mut self.device);
        self.save_with(whole, grid, &|t| slot.lagging_in_saved(t));
        self.device = slot;
        self.device.saved_taken();
        #[cfg(test)]
        assert!(
            self.checkpoint_is_whole(),
            "a tile changed since the last checkpoint without being marked"
        );
    }

    /// Whether the checkpoint's copy already holds the nodes of every tile lagging on the
    /// CPU (so a checkpoint need not bring them up to date), with a copy by tile to follow.
    pub(super) fn saved_holds_lagging(&self) -> bool {
        self.device.saved_holds_lagging() && self.activity.is_some() && self.saved_takes_tiles()
    }

    /// Whether the next checkpoint copies by tile into an existing copy (not everything).
    pub(super) fn saved_takes_tiles(&self) -> bool {
        self.saved.is_some() && !self.changed.all
    }

    /// [`Membrane::save`]: the whole model where `whole`, else the changed tiles of the grid
    /// `grid` ([`Membrane::tile_grid`]), but for the nodes of those that `in_saved` says the
    /// copy holds already.
    pub(super) fn save_with(
        &mut self,
        whole: bool,
        (tr, tc, tiles_c): (usize, usize, usize),
        in_saved: &dyn Fn(usize) -> bool,
    ) {
        match &mut self.saved {
            Some(s) if !whole => {
                let (rows, cols) = (self.rows, self.cols);
                let per = rows * cols;
                let c = &self.changed;
                for &t in &c.marked {
                    let (r0, c0) = ((t / tiles_c) * tr, (t % tiles_c) * tc);
                    let (r1, c1) = ((r0 + tr).min(rows), (c0 + tc).min(cols));
                    let springs = c.springs.get(t).copied().unwrap_or(false);
                    let nodes = !in_saved(t);
                    for l in 0..LAYERS {
                        for i in r0..r1 {
                            let b = l * rows + i;
                            let row = |k: usize, n: usize| {
                                (b * n + k) * cols + c0..(b * n + k) * cols + c1
                            };
                            if nodes {
                                for k in 0..6 {
                                    let r = row(k, 6);
                                    s.state[r.clone()].copy_from_slice(&self.state.data[r]);
                                }
                            }
                            if springs {
                                for k in 0..field::COUNT {
                                    let r = row(k, field::COUNT);
                                    s.rows_data[r.clone()].copy_from_slice(&self.rows_data[r]);
                                }
                                let r = l * per + i * cols + c0..l * per + i * cols + c1;
                                s.released[r.clone()].copy_from_slice(&self.released[r]);
                            }
                        }
                    }
                }
            }
            Some(s) => {
                s.state.clone_from(&self.state.data);
                s.rows_data.clone_from(&self.rows_data);
                s.released.clone_from(&self.released);
            }
            None => {
                self.saved = Some(Box::new(Saved {
                    state: self.state.data.clone(),
                    rows_data: self.rows_data.clone(),
                    released: self.released.clone(),
                }));
            }
        }
        self.changed.clear();
    }

    /// The checkpoint's copy of the nodes, for a device's step to bring the tiles it leaves
    /// lagging into (`device_lazy.rs`); none before the first checkpoint.
    pub(super) fn saved_nodes(&mut self) -> Option<&mut [f32]> {
        self.saved.as_deref_mut().map(|s| s.state.as_mut_slice())
    }

    /// The model back at its checkpoint (where there is one); nothing differs from it then.
    pub(super) fn load(&mut self) {
        if let Some(s) = &self.saved {
            self.state.data.clone_from(&s.state);
            self.rows_data.clone_from(&s.rows_data);
            self.springs_version = self.springs_version.wrapping_add(1);
            self.released.clone_from(&s.released);
            self.changed.clear();
        }
    }

    /// Whether the checkpoint holds what a copy of the whole model would (a test's check on
    /// the marks: every tile that changed was marked), the device's newest state of the tiles
    /// lagging on the CPU included.
    #[cfg(test)]
    pub(super) fn checkpoint_is_whole(&self) -> bool {
        let state = self.current_state();
        self.saved.as_ref().is_some_and(|s| {
            s.state
                .iter()
                .map(|v| v.to_bits())
                .eq(state.iter().map(|v| v.to_bits()))
                && s.rows_data
                    .iter()
                    .map(|v| v.to_bits())
                    .eq(self.rows_data.iter().map(|v| v.to_bits()))
                && s.released == self.released
        })
    }
}
