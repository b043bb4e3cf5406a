//! The scenario's optional `[tree]`: the vessel tree as centrelines with diameters, the named
//! vessel the task asks to cannulate, the weaker wall at the ostia and which way the
//! patient's head lies. Without it the vessel is the paper's bifurcation from `[vessel]`'s
//! lengths and angle, and `task.branch` names the target by number.

use crate::models::skeleton::tree::{self, Centreline, SNAP_M, TubeSpec};
use crate::models::skeleton::vessel::Branch;
use crate::scenario::InputError;
use glam::DVec3;
use serde::Deserialize;

/// The shortest segment of a centreline, m.
pub const SHORTEST_SEGMENT_M: f64 = 0.005;
/// The sharpest turn between a centreline's segments, degrees: sharper, the rings of the
/// two tubes would cross well inside the bend.
pub const SHARPEST_TURN_DEG: f64 = 60.0;

/// The tree.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreeTable {
    /// The vessel the task asks to cannulate, by name (to `task.reach_m` along it).
    pub target: String,
    /// The wall within this of where two vessels' walls meet is an ostium's (or a
    /// carina's), m.
    #[serde(default = "default_ostium_m")]
    pub ostium_m: f64,
    /// The ostium's wall punctures at this share of an instrument's puncture force.
    #[serde(default = "default_ostium_strength")]
    pub ostium_strength: f64,
    /// Where the patient's head lies (in the x y plane; the anterior is +z), for the
    /// fluoroscope's views.
    #[serde(default = "default_head")]
    pub head: [f64; 3],
    /// The vessels, each parent before its children; the first is the root, whose first
    /// point is the inlet.
    pub vessel: Vec<VesselEntry>,
}

/// One vessel: its name, its parent's name (none for the root), its outer diameter and its
/// centreline's points.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VesselEntry {
    pub name: String,
    #[serde(default)]
    pub parent: Option<String>,
    pub diameter_m: f64,
    pub points_m: Vec<[f64; 3]>,
}

fn default_ostium_m() -> f64 {
    0.004
}

fn default_ostium_strength() -> f64 {
    0.6
}

fn default_head() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}

impl TreeTable {
    /// The tree's rules: names, parents, sizes, shapes; `wall_m` the wall's thickness,
    /// `catheter_m` the catheter's diameter (it must fit every vessel from the inlet to the
    /// target), `reach_m` the task's depth into the target.
    pub fn validate(
        &self,
        file: &str,
        wall_m: f64,
        catheter_m: f64,
        reach_m: f64,
    ) -> Result<(), InputError> {
        let key = |k: usize, what: &str| format!("tree.vessel[{k}].{what}");
        InputError::require(!self.vessel.is_empty(), file, "tree.vessel", || {
            "expected at least a root and the target vessel".into()
        })?;
        for (what, x, (lo, hi)) in [
            ("tree.ostium_m", self.ostium_m, (0.0, 0.05)),
            ("tree.ostium_strength", self.ostium_strength, (0.1, 1.0)),
        ] {
            InputError::require((lo..=hi).contains(&x), file, what, || {
                format!("must be between {lo} and {hi}, got {x}")
            })?;
        }
        let head = DVec3::from_array(self.head);
        InputError::require(
            head.is_finite() && head.z == 0.0 && head.length() > 1e-6,
            file,
            "tree.head",
            || format!("expected a direction in the x y plane, got {:?}", self.head),
        )?;
        for (k, v) in self.vessel.iter().enumerate() {
            self.check_vessel(file, k, v, wall_m)?;
        }
        let target = self.target_index().ok_or_else(|| {
            let names: Vec<&str> = self.vessel.iter().map(|v| v.name.as_str()).collect();
            InputError::new(
                file,
                "tree.target",
                format!(
                    "expected one of the tree's vessels {names:?}, got {:?}",
                    self.target
                ),
            )
        })?;
        InputError::require(target > 0, file, "tree.target", || {
            format!("expected a branch, not the root {:?}", self.target)
        })?;
        // The catheter goes from the inlet to the target: it must fit each vessel on the way.
        let mut at = Some(target);
        while let Some(k) = at {
            let v = &self.vessel[k];
            let lumen = v.diameter_m - 2.0 * wall_m;
            InputError::require(catheter_m < lumen, file, &key(k, "diameter_m"), || {
                format!(
                    "the catheter ({catheter_m} m) goes through {:?} to the target: expected \
                     a lumen wider than it, got {lumen} m",
                    v.name
                )
            })?;
            at = self.parent_index(k);
        }
        let length = self.centrelines()[target].length_m();
        InputError::require(reach_m <= length, file, "task.reach_m", || {
            format!(
                "expected a reach within the target {:?}'s {length} m, got {reach_m} m",
                self.target
            )
        })
    }

    fn check_vessel(
        &self,
        file: &str,
        k: usize,
        v: &VesselEntry,
        wall_m: f64,
    ) -> Result<(), InputError> {
        let key = |what: &str| format!("tree.vessel[{k}].{what}");
        InputError::require(
            !v.name.trim().is_empty() && !self.vessel[..k].iter().any(|o| o.name == v.name),
            file,
            &key("name"),
            || format!("expected a name of its own, got {:?}", v.name),
        )?;
        let d = v.diameter_m;
        InputError::require(
            d.is_finite() && (0.002..=0.05).contains(&d),
            file,
            &key("diameter_m"),
            || format!("must be between 0.002 and 0.05 m, got {d}"),
        )?;
        crate::scenario::check_wall(
            file,
            &key("diameter_m"),
            wall_m,
            (0.25, d),
            "a quarter of the vessel's diameter",
        )?;
        let points: Vec<DVec3> = v.points_m.iter().map(|p| DVec3::from_array(*p)).collect();
        InputError::require(
            points.len() >= 2 && points.iter().all(|p| p.is_finite() && p.length() < 10.0),
            file,
            &key("points_m"),
            || "expected two or more points [x, y, z] in m, each finite and within 10 m".into(),
        )?;
        for (j, w) in points.windows(2).enumerate() {
            let len = w[0].distance(w[1]);
            InputError::require(
                len >= SHORTEST_SEGMENT_M,
                file,
                &key(&format!("points_m[{}]", j + 1)),
                || {
                    format!(
                        "expected {SHORTEST_SEGMENT_M} m or more from the point before, got {len} m"
                    )
                },
            )?;
        }
        for (j, w) in points.windows(3).enumerate() {
            let turn = tree::turn_deg(w[1] - w[0], w[2] - w[1]);
            InputError::require(
                turn <= SHARPEST_TURN_DEG,
                file,
                &key(&format!("points_m[{}]", j + 1)),
                || format!("expected a turn of at most {SHARPEST_TURN_DEG} degrees, got {turn:.1}"),
            )?;
        }
        if k == 0 {
            InputError::require(v.parent.is_none(), file, &key("parent"), || {
                "the first vessel is the root: it has no parent".into()
            })?;
            let along_x = (points[1] - points[0]).normalize_or_zero();
            InputError::require(
                points[0] == DVec3::ZERO && along_x.y == 0.0 && along_x.z == 0.0 && along_x.x > 0.0,
                file,
                &key("points_m"),
                || "the root starts at the inlet, [0, 0, 0], and runs along +x from it".into(),
            )?;
            return Ok(());
        }
        let parent = self.parent_index(k).ok_or_else(|| {
            InputError::new(
                file,
                &key("parent"),
                format!(
                    "expected the name of a vessel listed before it, got {:?}",
                    v.parent.as_deref().unwrap_or("")
                ),
            )
        })?;
        let p = &self.vessel[parent];
        let line = Centreline {
            name: p.name.clone(),
            parent: None,
            diameter_m: p.diameter_m,
            points: p.points_m.iter().map(|q| DVec3::from_array(*q)).collect(),
        };
        let lumen = 0.5 * p.diameter_m - wall_m;
        let (j, t, off) = line.nearest(points[0]).unwrap_or((0, 0.0, f64::INFINITY));
        InputError::require(off <= lumen, file, &key("points_m[0]"), || {
            format!(
                "expected its start inside {:?}'s lumen (within {lumen} m of its centreline), \
                 got {off} m from it",
                p.name
            )
        })?;
        InputError::require(j > 0 || t > SNAP_M, file, &key("points_m[0]"), || {
            format!("expected it to leave {:?} past that vessel's start", p.name)
        })
    }

    fn parent_index(&self, k: usize) -> Option<usize> {
        let name = self.vessel.get(k)?.parent.as_ref()?;
        self.vessel[..k].iter().position(|v| &v.name == name)
    }

    /// The target's place among the vessels.
    pub fn target_index(&self) -> Option<usize> {
        self.vessel.iter().position(|v| v.name == self.target)
    }

    /// The patient's head, a unit vector.
    pub fn head(&self) -> DVec3 {
        DVec3::from_array(self.head).normalize_or(DVec3::X)
    }

    /// The centrelines (parents by place).
    pub fn centrelines(&self) -> Vec<Centreline> {
        self.vessel
            .iter()
            .enumerate()
            .map(|(k, v)| Centreline {
                name: v.name.clone(),
                parent: self.parent_index(k),
                diameter_m: v.diameter_m,
                points: v.points_m.iter().map(|p| DVec3::from_array(*p)).collect(),
            })
            .collect()
    }

    /// The tree's tubes and named vessels.
    pub fn tubes(&self) -> (Vec<TubeSpec>, Vec<Branch>) {
        tree::tubes_and_branches(&self.centrelines())
    }

    /// Every point `scale` times as far from the inlet (the benchmark's longer vessels).
    pub fn scale_lengths(&mut self, scale: f64) {
        for v in &mut self.vessel {
            for p in &mut v.points_m {
                p.iter_mut().for_each(|c| *c *= scale);
            }
        }
    }
}

#[cfg(test)]
#[path = "tree_tests.rs"]
mod tests;
