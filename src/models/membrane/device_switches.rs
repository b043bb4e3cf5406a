//! Switches and counts of the membrane's device for the tests: each switch puts back one
//! way the device did a step before (to compare the bytes or the traffic), each count tells
//! what went up.

use super::super::Membrane;

impl Membrane {
    /// Sends every synced tile's state up at each step, whether the device holds it or not
    /// (to compare with the steps that send only what the device lacks).
    pub(crate) fn gpu_resend_every_step(&mut self, on: bool) {
        if let Some(d) = &mut self.device.on {
            d.resend = on;
        }
    }

    /// Leaves the halo's placing to the CPU, as before the device placed it.
    pub(crate) fn gpu_place_halo_on_cpu(&mut self, on: bool) {
        if let Some(d) = &mut self.device.on {
            d.cpu_places_halo = on;
        }
    }

    /// Leave layer 0's targets to the CPU, as before the device placed them from the chain's
    /// pose (to compare).
    pub(crate) fn gpu_place_targets_on_cpu(&mut self, on: bool) {
        if let Some(d) = &mut self.device.on {
            d.cpu_places_targets = on;
        }
    }

    /// Leaves a frame's lagging nodes in the runs, copied whole with the step announced
    /// before it, as before the device gathered the drawn nodes (to compare).
    pub(crate) fn gpu_frames_copy_runs(&mut self, on: bool) {
        if let Some(d) = &mut self.device.on {
            d.gather_refused = on;
            d.gather = None;
        }
    }

    /// Tiles whose layer-0 attachments went up to the device so far (none on the CPU).
    pub(crate) fn gpu_attachments_sent(&self) -> Option<u64> {
        self.device.on.as_ref().map(|d| d.attach_sent)
    }

    /// Reads every awake tile back with each step, as before only the tiles the CPU reads
    /// next came back (to compare).
    pub(crate) fn gpu_read_back_everything(&mut self, on: bool) {
        if let Some(d) = &mut self.device.on {
            d.books.eager = on;
        }
    }

    /// Tiles that came back with a step so far, and the round trips that brought lagging
    /// tiles up to date (none on the CPU).
    pub(crate) fn gpu_readback_counts(&self) -> Option<(u64, u64)> {
        self.device
            .on
            .as_ref()
            .map(|d| (d.books.tiles_back, d.books.catch_ups))
    }

    /// Frames' reads of lagging nodes that copied runs on the device first (none on the
    /// CPU).
    pub(crate) fn gpu_frame_copies(&self) -> Option<u64> {
        let d = self.device.on.as_ref()?;
        Some(
            d.books
                .frame_copies
                .load(std::sync::atomic::Ordering::Relaxed),
        )
    }

    /// Bytes the last step brought back of the tiles' state (none on the CPU).
    pub(crate) fn gpu_last_readback_bytes(&self) -> Option<u64> {
        self.device.on.as_ref().map(|d| d.books.last_readback_bytes)
    }

    /// Awake tiles whose newest state only the device holds (none on the CPU).
    pub(crate) fn gpu_tiles_behind(&self) -> Option<usize> {
        self.device.on.as_ref().map(|d| d.books.behind_count())
    }

    /// Tiles whose state went up to the device so far (none on the CPU).
    pub(crate) fn gpu_tiles_sent(&self) -> Option<u64> {
        self.device.on.as_ref().map(|d| d.tiles_sent)
    }
}
