//! The sandbox's scenario file: timing, the block's size and resolution, its soft-body
//! parameters (the `[block]` table, named like the model so the window's save-back writes
//! where it read), the instruments and the task. Every number has its entry in a parameter
//! table; the tables check the ranges, and the checks that tie values together follow by
//! hand. An error names the file, the key and the expected range.

use crate::models::SoftBodyParams;
use crate::params::{ParamSpec, Params};
use crate::scenario::InputError;
use serde::Deserialize;

/// The name scenarios and traces give this procedure.
pub const NAME: &str = "sandbox";
/// The model, and the scenario table that holds its parameters.
pub const MODEL: &str = "block";

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

/// A block edge's length, m.
const EDGE: ParamSpec = ParamSpec::new("", "m", 0.0, (0.01, 0.3), "");

impl Params for Geometry {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::of(
            EDGE,
            "size_m[0]",
            0.06,
            "the block's width along x; it rests on the table top (y = 0), centred on the \
             origin in x and z",
        ),
        ParamSpec::of(EDGE, "size_m[1]", 0.03, "its height along y"),
        ParamSpec::of(EDGE, "size_m[2]", 0.04, "its depth along z"),
        ParamSpec::new(
            "resolution",
            "cells",
            24.0,
            (2.0, 256.0),
            "cells along the longest edge; the others get as many as keep the cells square \
             (24: 2.5 mm cells, 3456 triangles; at most 200000 points)",
        )
        .whole(),
    ];

    fn get(&self, key: &str) -> Option<f64> {
        Some(match key {
            "size_m[0]" => self.size_m[0].into(),
            "size_m[1]" => self.size_m[1].into(),
            "size_m[2]" => self.size_m[2].into(),
            "resolution" => self.resolution.into(),
            _ => return None,
        })
    }

    fn set(&mut self, key: &str, v: f64) -> bool {
        let f = v as f32;
        match key {
            "size_m[0]" => self.size_m[0] = f,
            "size_m[1]" => self.size_m[1] = f,
            "size_m[2]" => self.size_m[2] = f,
            // Saturates at 0 and u32::MAX (`as` does); the table checks the range.
            "resolution" => self.resolution = v as u32,
            _ => return false,
        }
        true
    }
}

impl Params for Tools {
    const SPECS: &'static [ParamSpec] = &[ParamSpec::new(
        "probe_tip_radius_m",
        "m",
        0.004,
        (5e-4, 0.02),
        "radius of the probe's rigid ball tip (an 8 mm ball)",
    )];

    crate::param_fields!(probe_tip_radius_m);
}

/// The shallowest press a scenario may ask for, m.
const MIN_PROBE_DEPTH_M: f64 = 5e-4;
/// The deepest: half the tallest block, m. A hand check holds it to half the block's own
/// height.
const MAX_PROBE_DEPTH_M: f64 = 0.15;

impl Params for Task {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "probe_depth_m",
            "m",
            0.005,
            (MIN_PROBE_DEPTH_M, MAX_PROBE_DEPTH_M),
            "how far below the undeformed top the probe's tip must press; at most half the \
             block's height",
        ),
        ParamSpec::new(
            "lift_height_m",
            "m",
            0.01,
            (1e-3, 0.05),
            "how far the grasped top must be lifted before it is let go",
        ),
        crate::scenario::Timing::target_time(10.0, crate::scenario::Timing::TARGET_TIME_DOC),
    ];

    crate::param_fields!(probe_depth_m, lift_height_m, target_time_s);
}

crate::scenario_tables! {
    dt: default,
    nodes: points,
    tables: [
        geometry: Geometry,
        /// The block's soft body.
        block: SoftBodyParams,
        tools: Tools,
        grasper: crate::scenario::Grasper,
        task: Task,
    ],
    moved: crate::scenario::Grasper::MOVED_FROM_TOOLS,
}

impl Scenario {
    /// Cells along x, y and z: the longest edge gets `resolution`, the others as many as keep
    /// the cells square (at least one).
    pub fn cells(&self) -> [u32; 3] {
        let g = &self.geometry;
        crate::mesh::block::divisions(glam::Vec3::from(g.size_m), g.resolution)
    }

    /// Simulated points: one per triangle of the block's surface.
    pub fn points(&self) -> u64 {
        crate::mesh::block::triangle_count(glam::Vec3::from(self.geometry.size_m), self.cells())
    }

    /// The tables' ranges, then the checks that tie values together.
    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        self.validate_tables(file)?;
        let g = &self.geometry;
        crate::scenario::check_size(
            file,
            "geometry.resolution",
            self.points(),
            MAX_POINTS,
            |n| {
                format!("asks for {n} simulated points; at most {MAX_POINTS}: lower the resolution")
            },
        )?;
        let k = &self.task;
        // The probe may not be asked to go through more than half the block.
        let half_height = 0.5 * g.size_m[1];
        crate::scenario::check_number(
            file,
            "task.probe_depth_m",
            k.probe_depth_m,
            (MIN_PROBE_DEPTH_M as f32, half_height),
            "m",
        )?;
        Ok(())
    }
}
