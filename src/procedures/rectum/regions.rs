//! Named regions of the membrane: the dissection target (the plane between layers 2 and 3,
//! the paper's "second and third layer", over a stated length and the whole circumference)
//! and the vulnerable structures the hook must not touch (the ureters on the side walls, the
//! pelvic nerve plexus low and to the sides) — each a band of grid rows and columns on given
//! layers, so a node's region is one lookup. Columns are counted from the front (anterior,
//! +y) towards +z, which this frame takes as the patient's left.
//!
//! Where they lie (documented choices, from the anatomy the paper's procedure dissects): the
//! ureters run down the pelvic side walls lateral to the mesorectum in its upper part; the
//! inferior hypogastric (pelvic) plexus lies on the side walls low in the pelvis, in front of
//! the lateral ligaments, close to the mesorectal fascia; the target plane (the "holy plane"
//! of total mesorectal excision) runs all the way round between the visceral and parietal
//! fasciae.

use crate::models::membrane::LAYERS;

/// A region's id: its index in [`REGIONS`]; 0 is "none".
pub type RegionId = u8;

/// What a region is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RegionKind {
    /// The tissue to dissect.
    Target,
    /// A structure that must not be touched with the hook.
    Vulnerable,
}

/// One region: the layers it covers, its rows as fractions of the length (from the top of
/// the section), and its columns as an arc in degrees from the front towards +z (may wrap).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    pub name: &'static str,
    /// The name alarms show.
    pub label: &'static str,
    pub kind: RegionKind,
    pub layers: [bool; LAYERS],
    pub rows: (f32, f32),
    pub arc_deg: (f32, f32),
}

/// The target's id (the first region).
pub const TARGET: RegionId = 1;

/// The regions, id = index + 1.
pub const REGIONS: [Region; 5] = [
    Region {
        name: "dissection_plane",
        label: "dissection plane",
        kind: RegionKind::Target,
        layers: [false, true, true, false],
        rows: (0.2, 0.8),
        arc_deg: (0.0, 360.0),
    },
    Region {
        name: "ureter_left",
        label: "left ureter",
        kind: RegionKind::Vulnerable,
        layers: [false, false, false, true],
        rows: (0.0, 0.5),
        arc_deg: (80.0, 100.0),
    },
    Region {
        name: "ureter_right",
        label: "right ureter",
        kind: RegionKind::Vulnerable,
        layers: [false, false, false, true],
        rows: (0.0, 0.5),
        arc_deg: (260.0, 280.0),
    },
    Region {
        name: "pelvic_plexus_left",
        label: "left pelvic nerve plexus",
        kind: RegionKind::Vulnerable,
        layers: [false, false, true, true],
        rows: (0.65, 1.0),
        arc_deg: (45.0, 75.0),
    },
    Region {
        name: "pelvic_plexus_right",
        label: "right pelvic nerve plexus",
        kind: RegionKind::Vulnerable,
        layers: [false, false, true, true],
        rows: (0.65, 1.0),
        arc_deg: (285.0, 315.0),
    },
];

/// The region of [`REGIONS`] with this id.
pub fn region(id: RegionId) -> Option<&'static Region> {
    (id as usize).checked_sub(1).and_then(|k| REGIONS.get(k))
}

/// Whether `deg` lies on the arc `(from, to)` (degrees, from the front towards +z; wraps when
/// `to < from`).
fn on_arc(deg: f32, (from, to): (f32, f32)) -> bool {
    if to - from >= 360.0 {
        return true;
    }
    let (d, a, b) = (
        deg.rem_euclid(360.0),
        from.rem_euclid(360.0),
        to.rem_euclid(360.0),
    );
    if a <= b {
        d >= a && d < b
    } else {
        d >= a || d < b
    }
}

/// Each membrane node's region (0: none), `node = (l * rows + i) * cols + j`. A node in two
/// regions takes the vulnerable one.
pub fn map(rows: usize, cols: usize) -> Vec<RegionId> {
    map_with(rows, cols, &REGIONS)
}

/// [`map`] with the target's rows and arc set by a scenario: [`REGIONS`] with the target's
/// extent replaced.
pub fn map_for_target(
    rows: usize,
    cols: usize,
    target_rows: (f32, f32),
    target_arc_deg: (f32, f32),
) -> Vec<RegionId> {
    let mut regions = REGIONS;
    regions[0].rows = target_rows;
    regions[0].arc_deg = target_arc_deg;
    map_with(rows, cols, &regions)
}

/// Whether grid row `i` of `rows`, column `j` of `cols` lies in `r` (on any of its layers).
pub fn covers(r: &Region, rows: usize, cols: usize, i: usize, j: usize) -> bool {
    let s = (i as f32 + 0.5) / rows as f32;
    let deg = 360.0 * j as f32 / cols as f32;
    s >= r.rows.0 && s < r.rows.1 && on_arc(deg, r.arc_deg)
}

fn map_with(rows: usize, cols: usize, regions: &[Region; 5]) -> Vec<RegionId> {
    let mut out = vec![0; LAYERS * rows * cols];
    for l in 0..LAYERS {
        for i in 0..rows {
            let s = (i as f32 + 0.5) / rows as f32;
            for j in 0..cols {
                let deg = 360.0 * j as f32 / cols as f32;
                let mut id = 0;
                for (k, r) in regions.iter().enumerate() {
                    let inside =
                        r.layers[l] && s >= r.rows.0 && s < r.rows.1 && on_arc(deg, r.arc_deg);
                    let better = id == 0 || r.kind == RegionKind::Vulnerable;
                    if inside && better {
                        id = (k + 1) as RegionId;
                    }
                }
                out[(l * rows + i) * cols + j] = id;
            }
        }
    }
    out
}
