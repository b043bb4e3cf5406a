use glam::Vec3;
use serde::Serialize;

/// One thing that happened in the simulation, stamped with the step it happened in.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimEvent {
    pub step: u64,
    #[serde(flatten)]
    pub kind: EventKind,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum EventKind {
    /// A tool started touching a model.
    Contact {
        tool: String,
        model: String,
    },
    /// A tool touched a vulnerable structure (an error).
    VesselContact {
        tool: String,
        model: String,
    },
    /// The laser found the tumour.
    TumourIdentified,
    /// A margin mark was placed; `margin_error_m` is its distance from the intended margin.
    MarginMarked {
        point: [f32; 3],
        margin_error_m: f32,
    },
    /// The laser removed `faces` triangles along `length_m` of path this step.
    Cut {
        model: String,
        faces: u32,
        length_m: f32,
    },
    /// Ties to the tumour were severed by the cut.
    TiesSevered {
        model: String,
        count: u32,
    },
    /// A tie tore because its force exceeded the threshold (an error if it was not cut).
    TieBroken {
        model: String,
        force_n: f32,
    },
    /// No tie or tissue joins the tumour to the kidney any more.
    TumourFreed,
    /// The freed tumour was lifted out of its bed.
    TumourRemoved,
    /// The grasper took hold of `vertices` points.
    Grasp {
        tool: String,
        model: String,
        vertices: u32,
    },
    Release {
        tool: String,
    },
    /// A task step was completed.
    TaskStep {
        name: String,
    },
    /// A model's state went non-finite; it was rolled back to `restored_step` and frozen.
    Quarantined {
        model: String,
        restored_step: u64,
    },
    /// The hand's controller stopped tracking; its instrument stays where it was.
    ControllerLost {
        hand: String,
    },
    /// The hand's controller is tracked again; its instrument follows it.
    ControllerRegained {
        hand: String,
    },
    /// The XR session was lost (headset unplugged, runtime gone); the simulation waits.
    SessionLost,
    /// A new XR session took over after a loss.
    SessionRestarted,
    /// The supervisor changed a model's tunable parameters (applied from this step on).
    TissueTuned {
        model: String,
        values: std::collections::BTreeMap<String, f32>,
    },
}

impl EventKind {
    pub fn name(&self) -> &'static str {
        match self {
            EventKind::Contact { .. } => "contact",
            EventKind::VesselContact { .. } => "vessel_contact",
            EventKind::TumourIdentified => "tumour_identified",
            EventKind::MarginMarked { .. } => "margin_marked",
            EventKind::Cut { .. } => "cut",
            EventKind::TiesSevered { .. } => "ties_severed",
            EventKind::TieBroken { .. } => "tie_broken",
            EventKind::TumourFreed => "tumour_freed",
            EventKind::TumourRemoved => "tumour_removed",
            EventKind::Grasp { .. } => "grasp",
            EventKind::Release { .. } => "release",
            EventKind::TaskStep { .. } => "task_step",
            EventKind::Quarantined { .. } => "quarantined",
            EventKind::ControllerLost { .. } => "controller_lost",
            EventKind::ControllerRegained { .. } => "controller_regained",
            EventKind::SessionLost => "session_lost",
            EventKind::SessionRestarted => "session_restarted",
            EventKind::TissueTuned { .. } => "tissue_tuned",
        }
    }

    pub fn marked(point: Vec3, margin_error_m: f32) -> Self {
        EventKind::MarginMarked {
            point: point.to_array(),
            margin_error_m,
        }
    }
}
