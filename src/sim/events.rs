use serde::{Serialize, Serializer};

/// One thing that happened in the simulation, stamped with the step it happened in. As JSON:
/// `{"step": N, "kind": "<name>", ...fields}`, the same shape for core and procedure events.
#[derive(Debug, Clone, PartialEq)]
pub struct SimEvent {
    pub step: u64,
    pub kind: EventKind,
}

impl Serialize for SimEvent {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::{Error, SerializeMap};
        let fields = match &self.kind {
            EventKind::Procedure(p) => p.fields.clone(),
            k => match serde_json::to_value(k).map_err(S::Error::custom)? {
                serde_json::Value::Object(mut m) => {
                    m.remove("kind");
                    m.values_mut().for_each(shortest_f32);
                    m
                }
                _ => serde_json::Map::new(),
            },
        };
        let mut map = s.serialize_map(Some(fields.len() + 2))?;
        map.serialize_entry("step", &self.step)?;
        map.serialize_entry("kind", self.kind.name())?;
        for (k, v) in &fields {
            map.serialize_entry(k, v)?;
        }
        map.end()
    }
}

/// Turns numbers that came from `f32` (an `f64` that an `f32` holds exactly) back into the
/// `f32`'s shortest decimal form, so JSON made through `serde_json::Value` reads `0.16010386`
/// as direct serialisation would, not `0.16010385751724243`.
pub fn shortest_f32(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Number(n) => {
            if let Some(x) = n.as_f64().filter(|_| !n.is_i64() && !n.is_u64()) {
                let f = x as f32;
                if f64::from(f) == x
                    && let Ok(short) = f.to_string().parse::<f64>()
                    && let Some(m) = serde_json::Number::from_f64(short)
                {
                    *n = m;
                }
            }
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(shortest_f32),
        serde_json::Value::Object(m) => m.values_mut().for_each(shortest_f32),
        _ => {}
    }
}

/// An event of one procedure's own (a target identified, a specimen removed): its name and
/// fields. The procedure types it in its folder and turns it into this; the core only counts,
/// logs and replays it.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcedureEvent {
    pub name: &'static str,
    pub fields: serde_json::Map<String, serde_json::Value>,
}

impl ProcedureEvent {
    /// An event called `name` whose fields are `fields` serialised (a struct, or `()` for
    /// none).
    pub fn new(name: &'static str, fields: impl Serialize) -> ProcedureEvent {
        let fields = match serde_json::to_value(fields) {
            Ok(serde_json::Value::Object(mut m)) => {
                m.values_mut().for_each(shortest_f32);
                m
            }
            _ => serde_json::Map::new(),
        };
        ProcedureEvent { name, fields }
    }
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
    VulnerableContact {
        tool: String,
        model: String,
    },
    /// A tool removed `faces` triangles along `length_m` of path this step.
    Cut {
        model: String,
        faces: u32,
        length_m: f32,
    },
    /// Ties between regions were severed by a cut.
    TiesSevered {
        model: String,
        count: u32,
    },
    /// A tie tore because its force exceeded the threshold (an error if it was not cut).
    TieBroken {
        model: String,
        force_n: f32,
    },
    /// A tie between two models (an attachment) tore: `what` names the attachment.
    Rupture {
        what: String,
        models: [String; 2],
        force_n: f32,
    },
    /// The grasper took hold of `vertices` points.
    Grasp {
        tool: String,
        model: String,
        vertices: u32,
    },
    Release {
        tool: String,
    },
    /// The supervisor's alarm went off for a tool (raised once when its condition begins).
    Alarm {
        tool: String,
        message: String,
    },
    /// A dynamic-assessment rule of the session's tree gave the trainee an instruction
    /// (raised once each time its condition begins).
    Instruction {
        rule: String,
        message: String,
    },
    /// A task step was completed.
    TaskStep {
        name: String,
    },
    /// An action of task step `step` was taken while `expected`, a step before it, was still
    /// to do (the procedure's order was not kept; assessment counts these).
    OutOfOrder {
        step: String,
        expected: String,
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
    /// A model's GPU failed (device lost, out of memory, a rejected command): it goes on on
    /// the CPU from its last good state; `reason` is what the device said.
    ComputeFallback {
        model: String,
        reason: String,
    },
    /// The supervisor changed a model's tunable parameters (applied from this step on).
    TissueTuned {
        model: String,
        values: std::collections::BTreeMap<String, f32>,
    },
    /// A procedure's own event.
    #[serde(skip)]
    Procedure(ProcedureEvent),
    /// A force-feedback output was limited to the device's nominal maximum (raised once when a
    /// run of limited servo ticks begins): `quantity` is `force_n` or `stiffness_n_per_m`,
    /// `requested` what the model asked for and `limit` what the device was given, in that
    /// quantity's unit.
    HapticClamp {
        hand: String,
        quantity: String,
        requested: f32,
        limit: f32,
    },
    /// The simulation stopped publishing haptic frames (`phase` `begin`: `silent_s` since the
    /// last one; the device's force fades to zero) or started again (`end`: `silent_s` the
    /// whole silence; the force ramps back).
    HapticStall {
        hand: String,
        phase: String,
        silent_s: f32,
    },
    /// The device's force gain changed course: `start` (the stylus held still, the start-up
    /// ramp from 0 begins), `full` (the start-up ramp reached 1), `recover` (after a stall or
    /// a non-finite value the force ramps back from `gain`), `recovered` (back at 1).
    HapticRamp {
        hand: String,
        phase: String,
        gain: f32,
    },
    /// A non-finite value reached the servo loop (`what`: `force`, `stiffness`, `position` or
    /// `velocity`); the device was given zero force (raised once when such a run begins).
    HapticNonFinite {
        hand: String,
        what: String,
    },
}

impl EventKind {
    pub fn name(&self) -> &'static str {
        match self {
            EventKind::Contact { .. } => "contact",
            EventKind::VulnerableContact { .. } => "vulnerable_contact",
            EventKind::Cut { .. } => "cut",
            EventKind::TiesSevered { .. } => "ties_severed",
            EventKind::TieBroken { .. } => "tie_broken",
            EventKind::Rupture { .. } => "rupture",
            EventKind::Grasp { .. } => "grasp",
            EventKind::Release { .. } => "release",
            EventKind::Alarm { .. } => "alarm",
            EventKind::Instruction { .. } => "instruction",
            EventKind::TaskStep { .. } => "task_step",
            EventKind::OutOfOrder { .. } => "out_of_order",
            EventKind::Quarantined { .. } => "quarantined",
            EventKind::ControllerLost { .. } => "controller_lost",
            EventKind::ControllerRegained { .. } => "controller_regained",
            EventKind::SessionLost => "session_lost",
            EventKind::SessionRestarted => "session_restarted",
            EventKind::ComputeFallback { .. } => "compute_fallback",
            EventKind::TissueTuned { .. } => "tissue_tuned",
            EventKind::Procedure(p) => p.name,
            EventKind::HapticClamp { .. } => "haptic_clamp",
            EventKind::HapticStall { .. } => "haptic_stall",
            EventKind::HapticRamp { .. } => "haptic_ramp",
            EventKind::HapticNonFinite { .. } => "haptic_non_finite",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn core_and_procedure_events_serialise_to_the_same_shape() {
        let core = SimEvent {
            step: 7,
            kind: EventKind::Cut {
                model: "organ".into(),
                faces: 3,
                length_m: 0.5,
            },
        };
        let text = serde_json::to_string(&core).unwrap_or_default();
        assert_eq!(
            text,
            r#"{"step":7,"kind":"cut","faces":3,"length_m":0.5,"model":"organ"}"#
        );
        #[derive(Serialize)]
        struct Marked {
            error_m: f32,
        }
        let own = SimEvent {
            step: 9,
            kind: EventKind::Procedure(ProcedureEvent::new("marked", Marked { error_m: 0.25 })),
        };
        assert_eq!(own.kind.name(), "marked");
        let text = serde_json::to_string(&own).unwrap_or_default();
        assert_eq!(text, r#"{"step":9,"kind":"marked","error_m":0.25}"#);
        // An f32 keeps its own shortest form; an f64 keeps all its digits.
        let mut v = serde_json::json!({"a": 0.16010386f32, "b": 0.1f64, "n": [3, 1.5f32]});
        shortest_f32(&mut v);
        assert_eq!(v.to_string(), r#"{"a":0.16010386,"b":0.1,"n":[3,1.5]}"#);
        let bare = SimEvent {
            step: 1,
            kind: EventKind::Procedure(ProcedureEvent::new("found", ())),
        };
        assert_eq!(
            serde_json::to_string(&bare).unwrap_or_default(),
            r#"{"step":1,"kind":"found"}"#
        );
    }
}
