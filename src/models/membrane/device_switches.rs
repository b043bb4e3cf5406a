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

    /// Tiles whose layer-0 attachments went up to the device so far (none on the CPU).
    pub(crate) fn gpu_attachments_sent(&self) -> Option<u64> {
        self.device.on.as_ref().map(|d| d.attach_sent)
    }

    /// Tiles whose state went up to the device so far (none on the CPU).
    pub(crate) fn gpu_tiles_sent(&self) -> Option<u64> {
        self.device.on.as_ref().map(|d| d.tiles_sent)
    }
}
