//! What of the device's step comes back to the CPU, and when. The device packs every awake
//! tile each step (`shaders/membrane_sync.wgsl`), but only the runs of tiles the CPU is
//! expected to read next come back with the step: the tiles an instrument's queries returned
//! this step ([`Membrane::awake_tiles_near`], the cut's search) and those the same query
//! would meet reaching a millimetre further (`active_near.rs`: where an instrument or the
//! tissue may be at the next step), and the tiles that may fall asleep at this step's check
//! (their offsets are taken from their positions). The other awake tiles are *behind* on the
//! CPU: the device holds their newest state, and its packed copy of it stays on the device
//! until the next step packs anew.
//!
//! A behind tile is brought up to date (its run copied from the packed copy, read back and
//! unpacked: one more round trip) before the CPU reads or writes it: when a query returns it,
//! when it falls asleep, and for everything at once before a checkpoint, a hash, or anything
//! that rewrites the model ([`Membrane::catch_up`]). Every awake tile is in the packed copy,
//! so the bytes are those of reading everything back each step (tested). A frame reads only
//! the positions of its drawn nodes of a behind tile, as the device left them, and leaves
//! the tile behind ([`Membrane::lagging_positions`]): a step announced before a frame
//! gathers them on the device and brings back only those (`device_drawn.rs`), once the
//! device has the frame's grid. Where a step copied every run to the readback (a checkpoint
//! was announced for it, or a frame before its grid was laid out), what reads a behind run
//! before the next step reads it there, with no copy on the device.
//!
//! Should a read fail (the device lost), the CPU's copy of the behind tiles is older than
//! the rest: the membrane goes back to its last checkpoint (taken when it went on the
//! device, then every checkpoint of its world), the device is dropped and the failure is
//! reported as an event.

use super::pack::{Run, as_floats, unpack};
use super::{Membrane, OnDevice};
use crate::gpu::RenderError;
use crate::gpu::compute;
use crate::models::membrane::active::Activity;
use glam::Vec3;
use std::borrow::Cow;

/// The per-tile books of what the CPU lags and what it read (kept in [`OnDevice`]).
#[derive(Debug, Default)]
pub(super) struct Books {
    /// Per tile: the CPU's copy lags the device's (an awake tile whose run did not come
    /// back).
    behind: Vec<bool>,
    behind_count: usize,
    /// Per tile: the run it was packed in at the last step.
    pub run_of: Vec<u32>,
    /// Tiles the CPU read since the last step (marks by tile, and the list to clear them).
    marks: Vec<bool>,
    marked: Vec<usize>,
    /// The tiles wanted back with this step (scratch; empty: every one).
    pub want: Vec<bool>,
    /// Read every awake tile back with each step (to compare; tests).
    pub eager: bool,
    /// Read every awake tile back with the next step only (a checkpoint follows where its
    /// copy cannot take the lagging tiles: [`super::Slot::checkpoint_next`]).
    pub once: bool,
    /// A frame follows the next step ([`super::Slot::read_whole_next`]): the drawn nodes of
    /// the tiles it leaves lagging are gathered for the frame (`device_drawn.rs`); before the
    /// device has the frame's grid, every awake tile's run is copied to the readback with
    /// it instead, the wanted ones unpacked as usual, so that the frame reads the others'
    /// drawn nodes there, and a catch-up before the next step unpacks them from there, with
    /// no copy on the device.
    pub frame_next: bool,
    /// Where the last step's packed runs start in the readback (bytes), all of them, where
    /// it copied every one (a frame or a checkpoint followed it); none once the readback
    /// holds anything else.
    pub in_readback: Option<u64>,
    /// A checkpoint follows the next step ([`super::Slot::checkpoint_next`]): the awake tiles
    /// it leaves lagging come back with it too, into the checkpoint's copy of the nodes (not
    /// the CPU's), where their state is finite.
    pub checkpoint_next: bool,
    /// The last step's lagging tiles went into the checkpoint's copy as the device left them
    /// (until the checkpoint is taken): a tile still lagging needs no catching up for it.
    pub lagging_in_saved: bool,
    /// Tiles that came back with a step, and round trips that copied behind runs on the
    /// device to bring them up to date, over the device's life (tests' counts).
    pub tiles_back: u64,
    pub catch_ups: u64,
    /// Frames' reads of lagging nodes that copied runs on the device first (tests' count).
    pub frame_copies: std::sync::atomic::AtomicU64,
    /// Bytes the last step's results brought back of the tiles' state: the runs, and the
    /// drawn nodes gathered for a frame.
    pub last_readback_bytes: u64,
}

impl Books {
    pub fn new(tiles: usize) -> Books {
        Books {
            behind: vec![false; tiles],
            run_of: vec![u32::MAX; tiles],
            marks: vec![false; tiles],
            want: vec![false; tiles],
            ..Books::default()
        }
    }

    /// Whether the CPU's copy of tile `t` lags the device's.
    pub fn is_behind(&self, t: usize) -> bool {
        self.behind.get(t).copied().unwrap_or(false)
    }

    /// Tiles the CPU's copy lags.
    #[cfg(test)]
    pub fn behind_count(&self) -> usize {
        self.behind_count
    }

    pub fn any_behind(&self) -> bool {
        self.behind_count > 0
    }

    /// Nothing lags: the CPU's copy is the model (it was rewritten, or everything came back).
    pub fn none_behind(&mut self) {
        if self.behind_count > 0 {
            self.behind.fill(false);
            self.behind_count = 0;
        }
    }

    /// The CPU read tiles `tiles` this step, or may read them at the next: they come back
    /// with it.
    pub fn mark(&mut self, tiles: &[usize]) {
        for &t in tiles {
            if let Some(m) = self.marks.get_mut(t)
                && !*m
            {
                *m = true;
                self.marked.push(t);
            }
        }
    }

    /// The tiles wanted back with a step of `dt` over `a`'s awake tiles, into `want`: those
    /// marked, and those whose still time reaches the sleep time with this step (they may
    /// fall asleep at its check); every one where eager (`want` empty). The marks are
    /// cleared.
    pub fn wanted(&mut self, a: &Activity, dt: f32, eager: bool) {
        self.want.clear();
        let every = eager || self.eager || std::mem::take(&mut self.once);
        if !every {
            self.want.resize(a.awake.len(), false);
            for &t in &self.marked {
                self.want[t] = true;
            }
            for &t in &a.list {
                let t = t as usize;
                self.want[t] |= a.may_sleep(t, dt);
            }
        }
        for &t in &self.marked {
            self.marks[t] = false;
        }
        self.marked.clear();
    }

    /// After a step over the awake tiles `list` packed in `runs`: the tiles of the runs that
    /// came back are current, the others behind.
    pub fn stepped(&mut self, list: &[u32], runs: &[Run]) {
        self.none_behind();
        for &t in list {
            let t = t as usize;
            let back = runs[self.run_of[t] as usize].wanted;
            self.behind[t] = !back;
            self.behind_count += usize::from(!back);
            self.tiles_back += u64::from(back);
        }
    }

    /// The runs (indices, ascending) holding a behind tile of `tiles` (of any tile where
    /// none).
    fn behind_runs(&self, tiles: Option<&[usize]>) -> Vec<usize> {
        if self.behind_count == 0 {
            return Vec::new();
        }
        let mut runs: Vec<usize> = match tiles {
            Some(ts) => ts
                .iter()
                .filter(|&&t| self.is_behind(t))
                .map(|&t| self.run_of[t] as usize)
                .collect(),
            None => (0..self.behind.len())
                .filter(|&t| self.behind[t])
                .map(|t| self.run_of[t] as usize)
                .collect(),
        };
        runs.sort_unstable();
        runs.dedup();
        runs
    }
}

impl super::Slot {
    /// Every awake tile comes back with the next step (something reads them all after it):
    /// into the readback, where the CPU reads what it needs of the tiles it lags (see
    /// [`Books::frame_next`]).
    pub fn read_whole_next(&mut self) {
        if let Some(d) = self.on.as_deref_mut() {
            d.books.frame_next = true;
        }
    }

    /// A checkpoint follows the next step: the tiles it leaves lagging come back with it
    /// into the checkpoint's copy (every awake tile into the CPU's where the device does not
    /// measure their finiteness).
    pub fn checkpoint_next(&mut self) {
        if let Some(d) = self.on.as_deref_mut() {
            if d.watcher.is_some() {
                d.books.checkpoint_next = true;
            } else {
                d.books.once = true;
            }
        }
    }

    /// Whether the checkpoint's copy holds the newest nodes of the tiles that lag on the
    /// CPU (the step before brought them there).
    pub fn saved_holds_lagging(&self) -> bool {
        self.on.as_deref().is_some_and(|d| d.books.lagging_in_saved)
    }

    /// Whether tile `t`'s newest nodes are in the checkpoint's copy and not the CPU's.
    pub fn lagging_in_saved(&self, t: usize) -> bool {
        self.on
            .as_deref()
            .is_some_and(|d| d.books.lagging_in_saved && d.books.is_behind(t))
    }

    /// The checkpoint was taken: its copy holds nothing the CPU's lacks.
    pub fn saved_taken(&mut self) {
        if let Some(d) = self.on.as_deref_mut() {
            d.books.lagging_in_saved = false;
        }
    }
}

impl OnDevice {
    /// Runs `which` (indices into the last step's runs) as the device packed them, handed to
    /// `read` with their places in what was read: from the readback where the last step
    /// left them all there (no copy on the device), else copied there first ([`fetch`]).
    /// Whether they were copied comes with the result.
    ///
    /// [`fetch`]: OnDevice::fetch
    fn read_runs<R>(
        &self,
        which: &[usize],
        read: impl FnOnce(&[Run], &[f32]) -> R,
    ) -> Result<(R, bool), RenderError> {
        let Some(at) = self.books.in_readback else {
            return self.fetch(which, read).map(|r| (r, true));
        };
        let floats = self
            .runs
            .iter()
            .map(|r| r.base + r.floats())
            .max()
            .unwrap_or(0);
        let got: Vec<Run> = which
            .iter()
            .filter_map(|&k| self.runs.get(k).copied())
            .collect();
        let (at, bytes) = (at as usize, floats * 4);
        let gpu = self.k.gpu();
        compute::with_mapped(gpu, &self.readback, (at + bytes).max(4) as u64, |raw| {
            as_floats(&raw[at..at + bytes], |v| read(&got, v))
        })
        .map(|r| (r, false))
    }

    /// Runs `which` (indices into the last step's runs) copied from the device's packed copy
    /// and read back, handed to `read` with their places in what was read (the runs in order,
    /// side by side).
    fn fetch<R>(
        &self,
        which: &[usize],
        read: impl FnOnce(&[Run], &[f32]) -> R,
    ) -> Result<R, RenderError> {
        let gpu = self.k.gpu();
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("membrane catch-up"),
            });
        let mut got = Vec::with_capacity(which.len());
        let mut at = 0usize;
        for &k in which {
            let Some(&r) = self.runs.get(k) else {
                continue;
            };
            let n = r.floats();
            let (from, to, bytes) = ((r.base * 4) as u64, (at * 4) as u64, (n * 4) as u64);
            encoder.copy_buffer_to_buffer(&self.packed_state, from, &self.readback, to, bytes);
            let mut r = r;
            r.base = at;
            got.push(r);
            at += n;
        }
        gpu.queue.submit([encoder.finish()]);
        compute::with_mapped(gpu, &self.readback, (at * 4).max(4) as u64, |raw| {
            let raw = &raw[..at * 4];
            as_floats(raw, |v| read(&got, v))
        })
    }
}

impl Membrane {
    /// Destroys the device under the membrane, as a driver reset or an unplugged GPU would
    /// (fault injection: the next step must fall back to the CPU). False when on the CPU.
    pub fn inject_device_loss(&mut self) -> bool {
        match &self.device.on {
            Some(d) => {
                d.k.gpu().device.destroy();
                true
            }
            None => false,
        }
    }

    /// Why the device was given up, once (the model reports it as an event).
    pub fn take_device_note(&mut self) -> Option<String> {
        self.device.note.take()
    }

    /// Brings the CPU's copy of every awake tile up to date where the membrane steps on a
    /// device (see `device_lazy.rs`): call before reading nodes other than those
    /// [`Membrane::awake_tiles_near`] returned. Nothing to do on the CPU.
    pub fn catch_up(&mut self) {
        catch_up_with(self, None);
    }

    /// Brings the CPU's copy of tiles `tiles` up to date (those behind the device).
    pub(in crate::models::membrane) fn catch_up_tiles(&mut self, tiles: &[usize]) {
        catch_up_with(self, Some(tiles));
    }

    /// The CPU reads tiles `tiles` now and (likely) next step: they are brought up to date and
    /// come back with the next step.
    pub(in crate::models::membrane) fn read_tiles(&mut self, tiles: &[usize]) {
        if let Some(d) = self.device.on.as_deref_mut() {
            d.books.mark(tiles);
            catch_up_with(self, Some(tiles));
        }
    }

    /// The CPU may read tiles `tiles` next step: they come back with this one.
    pub(in crate::models::membrane) fn read_tiles_next(&mut self, tiles: &[usize]) {
        if let Some(d) = self.device.on.as_deref_mut() {
            d.books.mark(tiles);
        }
    }

    /// Whether tile `t`'s CPU copy lags the device (never on the CPU).
    pub(in crate::models::membrane) fn tile_lags(&self, t: usize) -> bool {
        self.device
            .on
            .as_deref()
            .is_some_and(|d| d.books.is_behind(t))
    }

    /// The positions of nodes `nodes` of grid `g` (layer, row, column, and place; each of a
    /// tile the CPU lags) as the device left them at the last step, each into `out` at its
    /// place: where the last step gathered them (a frame was announced and `g` is laid out
    /// on the device: `device_drawn.rs`), from there; else from the runs, read where the last
    /// step left every run, else copied there first. The CPU's copy stays as it is, and its
    /// tiles lagging.
    pub(in crate::models::membrane) fn lagging_positions(
        &self,
        g: &crate::models::membrane::DrawnGrid,
        nodes: &[([usize; 3], usize)],
        out: &mut [Vec3],
    ) -> Result<(), RenderError> {
        let Some(d) = self.device.on.as_deref() else {
            return Ok(());
        };
        if let Some(read) = self.gathered_positions(g, nodes, out) {
            return read;
        }
        let run = |&([_, i, j], _): &([usize; 3], usize)| {
            d.books.run_of.get(self.tile_of(i, j)).map(|&k| k as usize)
        };
        let mut which: Vec<usize> = nodes.iter().filter_map(run).collect();
        which.sort_unstable();
        which.dedup();
        let _span = tracing::debug_span!("membrane_gpu_peek", runs = which.len()).entered();
        let read = d.read_runs(&which, |runs, v| {
            for n in nodes {
                let Some(r) = run(n)
                    .and_then(|k| which.binary_search(&k).ok())
                    .and_then(|x| runs.get(x))
                else {
                    continue;
                };
                let p = std::array::from_fn(|c| v.get(r.at(n.0, c)).copied().unwrap_or(0.0));
                if let Some(o) = out.get_mut(n.1) {
                    *o = Vec3::from_array(p);
                }
            }
        });
        let copies = &d.books.frame_copies;
        read.map(|((), copied)| {
            copies.fetch_add(u64::from(copied), std::sync::atomic::Ordering::Relaxed);
        })
    }

    /// Whether the queries mark the tiles ahead of them (the membrane steps on a device).
    pub(in crate::models::membrane) fn marks_ahead(&self) -> bool {
        self.device.on.is_some()
    }

    /// The whole state as the device has it, where the CPU's copy of some tiles lags it (a
    /// copy with those tiles read back); the CPU's own otherwise. A read that fails gives the
    /// CPU's copy, with a warning.
    pub(in crate::models::membrane) fn current_state(&self) -> Cow<'_, [f32]> {
        let Some(d) = self.device.on.as_deref().filter(|d| d.books.any_behind()) else {
            return Cow::Borrowed(&self.state.data);
        };
        let which = d.books.behind_runs(None);
        let mut data = self.state.data.clone();
        let dims = (self.rows, self.cols);
        match d.read_runs(&which, |runs, v| unpack(dims, &mut data, runs, v)) {
            Ok(_) => Cow::Owned(data),
            Err(e) => {
                tracing::warn!("the membrane's newest state could not be read back: {e}");
                Cow::Borrowed(&self.state.data)
            }
        }
    }

    /// Tests: whether tile `t` lags the device (none on the CPU).
    #[cfg(test)]
    pub(in crate::models::membrane) fn gpu_tile_behind(&self, t: usize) -> Option<bool> {
        self.device.on.as_deref().map(|d| d.books.is_behind(t))
    }

    /// Tests: panics where node `node`'s tile lags the device (a read the code must not make
    /// before [`Membrane::catch_up`]).
    #[cfg(test)]
    pub(in crate::models::membrane) fn assert_current(&self, node: usize) {
        if let Some(d) = self.device.on.as_deref() {
            let (_, i, j) = self.coords(node);
            let t = self.tile_of(i, j);
            assert!(
                !d.books.is_behind(t),
                "node {node} read on the CPU while its tile {t} lags the device"
            );
        }
    }
}

/// `step` on the membrane's device; none where it has none, or where `step` failed: the
/// failure is noted, the device dropped and the external forces put back for the CPU (the
/// CPU's state is written only by a step that succeeded).
pub(super) fn on_device<R>(
    m: &mut Membrane,
    step: impl FnOnce(&mut OnDevice, &mut Membrane) -> Result<R, RenderError>,
) -> Option<R> {
    let mut d = m.device.on.take()?;
    let external = m.external.clone();
    match step(&mut d, m) {
        Ok(r) => {
            m.device.on = Some(d);
            Some(r)
        }
        Err(e) => {
            m.external = external;
            lose_device(m, *d, &e);
            None
        }
    }
}

/// Brings the behind tiles among `tiles` (all where none) up to date; should the read fail,
/// the device is given up (see [`lose_device`]).
fn catch_up_with(m: &mut Membrane, tiles: Option<&[usize]>) {
    let Some(d) = m.device.on.as_deref_mut() else {
        return;
    };
    let which = d.books.behind_runs(tiles);
    if which.is_empty() {
        return;
    }
    let _span = tracing::debug_span!("membrane_gpu_catch_up", runs = which.len()).entered();
    let dims = (m.rows, m.cols);
    let data = &mut m.state.data;
    match d.read_runs(&which, |runs, v| unpack(dims, data, runs, v)) {
        Ok(((), copied)) => {
            let tiles_c = d.tiles_c as usize;
            d.books.catch_ups += u64::from(copied);
            for &k in &which {
                for t in d.runs[k].tiles(tiles_c) {
                    if d.books.behind.get(t).copied().unwrap_or(false) {
                        d.books.behind[t] = false;
                        d.books.behind_count -= 1;
                    }
                }
            }
        }
        Err(e) => {
            if let Some(d) = m.device.on.take() {
                lose_device(m, *d, &e);
            }
        }
    }
}

/// The device `d` (taken from `m`) failed with `e`: it is dropped and the failure noted; where
/// the CPU's copy lagged it, the membrane goes back to its last checkpoint (the external
/// forces of the step kept). Where the lagging tiles' newest nodes had come back into the
/// checkpoint's copy (a checkpoint was to follow this step), that copy is completed from the
/// CPU's for the other tiles and the membrane goes on from it: nothing is lost.
pub(super) fn lose_device(m: &mut Membrane, d: OnDevice, e: &RenderError) {
    let mut lagged = d.books.any_behind();
    if lagged && d.books.lagging_in_saved && m.saved_takes_tiles() {
        // The device's tiles are the active set's (`OnDevice::new`), out for its step or not.
        m.save_with(false, m.tile_grid(), &|t| d.books.is_behind(t));
        m.load();
        lagged = false;
    }
    drop(d);
    m.device.give_up(e);
    if lagged {
        let external = std::mem::take(&mut m.external);
        crate::sim::TissueModel::restore(m);
        m.external = external;
        if let Some(n) = &mut m.device.note {
            n.push_str(
                "; the device held the newest state of tiles away from the instruments, so \
                 the membrane went on from its last checkpoint",
            );
        }
    }
}
