//! The sandbox's scenario file: the block's size and resolution, its soft-body parameters
//! (the `[block]` table, named like the model so the window's save-back writes where it
//! read), the instruments and the task. Every value is range-checked here; an error names the
//! file, the key and the expected range.

use crate::models::SoftBodyParams;
use crate::scenario::InputError;
use serde::Deserialize;

/// The name scenarios and traces give this procedure.
pub const NAME: &str = "sandbox";
/// The model, and the scenario table that holds its parameters.
pub const MODEL: &str = "block";

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Always [`NAME`].
    pub procedure: String,
    /// Simulation step, s.
    pub dt_s: f32,
    /// Snapshots published for renderers per second, Hz.
    pub publish_hz: f32,
    pub geometry: Geometry,
    /// The block's soft body.
    pub block: SoftBodyParams,
    pub tools: Tools,
    pub task: Task,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    /// Width (x), height (y) and depth (z) of the block, m. It rests on the table top (y = 0),
    /// centred on the origin in x and z.
    pub size_m: [f32; 3],
    /// Cells along the block's longest edge; the other edges get as many as keep the cells
    /// square, so every face has about the same area.
    pub resolution: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tools {
    /// Radius of the probe's rigid ball tip, m.
    pub probe_tip_radius_m: f32,
    /// Radius of the open grasper's tip (a rigid sphere), m.
    pub grasper_tip_radius_m: f32,
    /// Reach of the closing jaws: points this close to the tip are held, m.
    pub grasp_radius_m: f32,
    /// Grip value at or above which the jaws close, 0..1.
    pub grip_threshold: f32,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Task {
    /// How far below the undeformed top the probe's tip must reach, m.
    pub probe_depth_m: f32,
    /// How far the grasped tissue must be lifted before it is let go, m.
    pub lift_height_m: f32,
    /// Time an expert needs, s (efficiency is full at or below it).
    pub target_time_s: f32,
}

/// Most simulated points a sandbox may ask for (a step stays well under a millisecond).
pub const MAX_POINTS: u64 = 200_000;

/// Range checks that name the file and key.
struct Check<'a> {
    file: &'a str,
}

impl Check<'_> {
    fn err(&self, key: &str, message: impl Into<String>) -> InputError {
        InputError::new(self.file, key, message)
    }

    fn num(&self, key: &str, v: f32, lo: f32, hi: f32, unit: &str) -> Result<(), InputError> {
        crate::scenario::check_number(self.file, key, v, (lo, hi), unit)
    }

    /// The soft body's table ranges (`SoftBodyParams::SPECS`).
    fn params(&self, table: &str, p: &SoftBodyParams) -> Result<(), InputError> {
        crate::params::validate(self.file, table, p)
    }
}

impl Scenario {
    /// Parses and checks scenario text; `file` names it in errors.
    pub fn parse(file: &str, text: &str) -> Result<Self, InputError> {
        let s: Scenario = toml::from_str(text).map_err(|e| InputError::toml(file, &e))?;
        s.validate(file)?;
        Ok(s)
    }

    /// Cells along x, y and z: the longest edge gets `resolution`, the others as many as keep
    /// the cells square (at least one).
    pub fn cells(&self) -> [u32; 3] {
        let g = &self.geometry;
        let longest = g.size_m.iter().copied().fold(f32::MIN_POSITIVE, f32::max);
        g.size_m
            .map(|s| ((s / longest * g.resolution as f32).round() as u32).max(1))
    }

    /// Simulated points: one per triangle, two triangles per cell on each of the six sides.
    pub fn points(&self) -> u64 {
        let [x, y, z] = self.cells().map(u64::from);
        4 * (x * y + y * z + z * x)
    }

    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        let c = Check { file };
        if self.procedure != NAME {
            return Err(c.err(
                "procedure",
                format!("must be \"{NAME}\", got \"{}\"", self.procedure),
            ));
        }
        c.num("dt_s", self.dt_s, 1e-4, 0.01, "s")?;
        c.num("publish_hz", self.publish_hz, 1.0, 1000.0, "Hz")?;
        let g = &self.geometry;
        for (i, s) in g.size_m.iter().enumerate() {
            c.num(&format!("geometry.size_m[{i}]"), *s, 0.01, 0.3, "m")?;
        }
        if !(2..=256).contains(&g.resolution) {
            return Err(c.err(
                "geometry.resolution",
                format!("must be between 2 and 256 cells, got {}", g.resolution),
            ));
        }
        if self.points() > MAX_POINTS {
            return Err(c.err(
                "geometry.resolution",
                format!(
                    "asks for {} simulated points; at most {MAX_POINTS}: lower the resolution",
                    self.points()
                ),
            ));
        }
        c.params(MODEL, &self.block)?;
        let t = &self.tools;
        c.num(
            "tools.probe_tip_radius_m",
            t.probe_tip_radius_m,
            5e-4,
            0.02,
            "m",
        )?;
        c.num(
            "tools.grasper_tip_radius_m",
            t.grasper_tip_radius_m,
            5e-4,
            0.02,
            "m",
        )?;
        c.num("tools.grasp_radius_m", t.grasp_radius_m, 5e-4, 0.02, "m")?;
        c.num("tools.grip_threshold", t.grip_threshold, 0.01, 1.0, "")?;
        let k = &self.task;
        // The probe may not be asked to go through more than half the block.
        let half_height = 0.5 * g.size_m[1];
        c.num(
            "task.probe_depth_m",
            k.probe_depth_m,
            5e-4,
            half_height,
            "m",
        )?;
        c.num("task.lift_height_m", k.lift_height_m, 1e-3, 0.05, "m")?;
        c.num("task.target_time_s", k.target_time_s, 1.0, 7200.0, "s")?;
        Ok(())
    }
}
