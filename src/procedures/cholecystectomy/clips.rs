//! Clips and cuts on the cystic duct and the cystic artery (the paper's task list: three clips
//! on the cystic duct, the cystic artery clipped, the cut between the clips).
//!
//! A clip lands on a vessel where the clip applier's jaw closes within reach of its
//! centreline, at an arc length from the vessel's first particle (m); a cut removes the
//! vessel's segment nearest the scissors' jaw. A cut is safe when at least two clips lie
//! between it and the patient (towards the common bile duct for the cystic duct, towards the
//! hepatic artery for the cystic artery): otherwise it is a bile leak (duct) or a bleeding
//! (artery), an error event. The record keeps every clip in the order placed and every cut,
//! for the report.

use crate::models::particles::Particles;
use crate::models::particles::chain::Chains;
use glam::Vec3;
use serde::Serialize;

/// Which end of a vessel's chain the patient is on (the other leads to the gallbladder).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PatientEnd {
    First,
    Last,
}

/// What cutting a vessel unclipped does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CutError {
    BileLeak,
    Bleeding,
}

/// A vessel that can be clipped and cut: its chain in [`Chains`], its name, where the
/// patient is, and what a cut with too few clips does.
#[derive(Debug, Clone, PartialEq)]
pub struct Clippable {
    pub chain: usize,
    pub name: &'static str,
    pub patient: PatientEnd,
    pub error: CutError,
}

/// A placed clip.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Clip {
    pub vessel: &'static str,
    /// Arc length from the vessel's first particle, m (at rest).
    pub at_m: f32,
    pub position: [f32; 3],
    pub time_s: f64,
}

/// A cut.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Cut {
    pub vessel: &'static str,
    pub at_m: f32,
    pub position: [f32; 3],
    pub time_s: f64,
    /// Clips between the cut and the patient, and towards the gallbladder.
    pub clips_patient_side: u32,
    pub clips_gallbladder_side: u32,
    /// What it did, if it was not safe.
    pub error: Option<CutError>,
}

/// Every clip and cut of a session.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ClipRecord {
    pub clips: Vec<Clip>,
    pub cuts: Vec<Cut>,
}

/// Where on chain `c` of `chains` the point `q` falls: its nearest segment, the arc length
/// there from the first particle at rest (m), the point on the centreline, and how far `q` is
/// from it (m).
fn locate(chains: &Chains, p: &Particles, c: usize, q: Vec3) -> Option<(usize, f32, Vec3, f32)> {
    let (k, d) = chains.nearest_segment(p, c, q)?;
    let (a, b) = chains.segment_ends(c, k)?;
    let (xa, xb) = (p.x[a as usize], p.x[b as usize]);
    let ab = xb - xa;
    let t = ((q - xa).dot(ab) / ab.length_squared().max(1e-20)).clamp(0.0, 1.0);
    let at = chains.rest_length_before(c, k) + t * chains.rest_length(c, k);
    Some((k, at, xa + ab * t, d))
}

impl ClipRecord {
    /// Places a clip on `v` where a jaw closed at `jaw` lands, if within `reach_m` of the
    /// vessel's centreline; returns it.
    pub fn clip(
        &mut self,
        chains: &Chains,
        p: &Particles,
        v: &Clippable,
        jaw: Vec3,
        reach_m: f32,
        time_s: f64,
    ) -> Option<Clip> {
        let (_, at, on, d) = locate(chains, p, v.chain, jaw)?;
        if d > reach_m {
            return None;
        }
        let c = Clip {
            vessel: v.name,
            at_m: at,
            position: on.to_array(),
            time_s,
        };
        self.clips.push(c);
        Some(c)
    }

    /// Cuts `v` at the segment nearest `jaw` if within `reach_m` (and not cut there already):
    /// counts the clips on either side and judges the cut. Returns it.
    pub fn cut(
        &mut self,
        chains: &mut Chains,
        p: &Particles,
        v: &Clippable,
        jaw: Vec3,
        reach_m: f32,
        time_s: f64,
    ) -> Option<Cut> {
        let (k, at, on, d) = locate(chains, p, v.chain, jaw)?;
        if d > reach_m || !chains.cut(v.chain, k) {
            return None;
        }
        let (mut toward_first, mut toward_last) = (0u32, 0u32);
        for c in self.clips.iter().filter(|c| c.vessel == v.name) {
            if c.at_m < at {
                toward_first += 1;
            } else {
                toward_last += 1;
            }
        }
        let (patient, gallbladder) = match v.patient {
            PatientEnd::First => (toward_first, toward_last),
            PatientEnd::Last => (toward_last, toward_first),
        };
        let cut = Cut {
            vessel: v.name,
            at_m: at,
            position: on.to_array(),
            time_s,
            clips_patient_side: patient,
            clips_gallbladder_side: gallbladder,
            error: (patient < 2).then_some(v.error),
        };
        self.cuts.push(cut);
        Some(cut)
    }

    /// Clips on vessel `name`.
    pub fn clips_on(&self, name: &str) -> usize {
        self.clips.iter().filter(|c| c.vessel == name).count()
    }
}

#[cfg(test)]
#[path = "clips_tests.rs"]
mod tests;
