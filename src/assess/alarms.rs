//! Alarms for the supervising surgeon: an instrument touching or nearing a vulnerable
//! structure, or a holding instrument pressing too hard. Dynamic assessment warns the trainee
//! in real time when a tool comes near vulnerable tissue; the force limit is each holding
//! instrument's full scale (the procedure says it). A beam has no force alarm: the force it
//! applies is the model's deforming pressure, not a load on an instrument.

use crate::sim::Hand;
use crate::sim::{ProcedureInfo, SessionStatus as Status, ToolInfo, ToolKind};

/// When to raise an alarm, and what the instruments are called.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlarmRules {
    /// A tool within this distance of a vulnerable structure, metres. Default 5 mm.
    pub near_m: f32,
    /// A contact force above this on a tool that holds or presses tissue, newtons. Default
    /// 3.5 N.
    pub force_n: f32,
    /// The instruments' names (left, right), for messages.
    pub names: [&'static str; 2],
    /// Which instruments the force limit applies to (not to a beam, whose force is the
    /// model's deforming pressure rather than a load on an instrument).
    pub force_on: [bool; 2],
}

impl Default for AlarmRules {
    fn default() -> Self {
        AlarmRules {
            near_m: 0.005,
            force_n: 3.5,
            names: ["left instrument", "right instrument"],
            force_on: [true, true],
        }
    }
}

impl AlarmRules {
    /// The default limits, with the procedure's instruments: the force limit at each
    /// holding or pressing instrument's full scale.
    pub fn for_procedure(info: &ProcedureInfo) -> Self {
        let holds = |t: &ToolInfo| t.kind != ToolKind::Laser;
        AlarmRules {
            names: info.tools.map(|t| t.name),
            force_on: info.tools.map(|t| holds(&t)),
            force_n: info
                .tools
                .iter()
                .filter(|t| holds(t))
                .map(|t| t.full_scale_n)
                .fold(f32::INFINITY, f32::min),
            ..AlarmRules::default()
        }
    }
}

/// What is wrong.
#[derive(Debug, Clone, PartialEq)]
pub enum Reason {
    Touching { structure: String },
    Near { structure: String, distance_m: f32 },
    Force { force_n: f32 },
}

/// One alarm: which instrument, why, and when it was raised (simulated seconds).
#[derive(Debug, Clone, PartialEq)]
pub struct Alarm {
    pub time_s: f64,
    pub hand: Hand,
    /// The instrument's name.
    pub tool: &'static str,
    pub reason: Reason,
}

impl Alarm {
    /// The banner's text in a surgeon's words, e.g. "The grasper is 4.0 mm from the renal
    /// artery" (a structure's name as people say it: `renal_artery` is the renal artery).
    pub fn message(&self) -> String {
        let tool = self.tool;
        let said = |s: &str| s.replace('_', " ");
        match &self.reason {
            Reason::Touching { structure } => {
                format!("The {tool} is touching the {}", said(structure))
            }
            Reason::Near {
                structure,
                distance_m,
            } => format!(
                "The {tool} is {:.1} mm from the {}",
                distance_m * 1000.0,
                said(structure)
            ),
            Reason::Force { force_n } => {
                format!("The {tool} is pressing too hard: {force_n:.1} N")
            }
        }
    }

    /// Kind of alarm, to tell one condition from another.
    fn kind(&self) -> usize {
        match self.reason {
            Reason::Touching { .. } => 0,
            Reason::Near { .. } => 1,
            Reason::Force { .. } => 2,
        }
    }
}

/// The alarms a status shows, worst first for each hand: touching before near (a tool that
/// touches is also near), then force.
pub fn conditions(rules: &AlarmRules, s: &Status) -> Vec<Alarm> {
    let mut out = Vec::new();
    for hand in Hand::BOTH {
        let k = hand.index();
        let near = s.near[k].as_ref();
        let mut push = |reason| {
            out.push(Alarm {
                time_s: s.time_s,
                hand,
                tool: rules.names[k],
                reason,
            })
        };
        if s.touching[k] {
            push(Reason::Touching {
                structure: near.map_or("a vulnerable structure".to_string(), |n| n.0.clone()),
            });
        } else if let Some((structure, d)) = near.filter(|n| n.1 <= rules.near_m) {
            push(Reason::Near {
                structure: structure.clone(),
                distance_m: *d,
            });
        }
        if rules.force_on[k] && s.force_n[k].is_finite() && s.force_n[k] > rules.force_n {
            push(Reason::Force {
                force_n: s.force_n[k],
            });
        }
    }
    out
}

/// Turns a stream of statuses into alarms raised once per episode: an alarm is logged when
/// its condition begins, not again while it lasts.
#[derive(Debug, Default)]
pub struct AlarmWatch {
    pub rules: AlarmRules,
    /// Conditions seen at the last update, by hand and kind.
    on: [[bool; 3]; 2],
}

impl AlarmWatch {
    pub fn new(rules: AlarmRules) -> Self {
        AlarmWatch {
            rules,
            on: [[false; 3]; 2],
        }
    }

    /// The current conditions, and those of them that just began.
    pub fn update(&mut self, s: &Status) -> (Vec<Alarm>, Vec<Alarm>) {
        let now = conditions(&self.rules, s);
        let mut on = [[false; 3]; 2];
        for a in &now {
            on[a.hand.index()][a.kind()] = true;
        }
        // Touching and near are one episode: coming close, then touching, is raised at each.
        let raised = now
            .iter()
            .filter(|a| !self.on[a.hand.index()][a.kind()])
            .cloned()
            .collect();
        self.on = on;
        (now, raised)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(t: f64) -> Status {
        Status {
            time_s: t,
            ..Status::default()
        }
    }

    #[test]
    fn an_approach_raises_near_then_touching_once_each_and_force_on_its_own() {
        let mut w = AlarmWatch::new(AlarmRules {
            names: ["jaws", "beam"],
            force_on: [true, false],
            ..AlarmRules::default()
        });
        let mut s = status(1.0);
        s.near[0] = Some(("structure A".into(), 0.008));
        assert_eq!(w.update(&s), (vec![], vec![]), "8 mm is not near");
        s.time_s = 1.5;
        s.near[0] = Some(("structure A".into(), 0.004));
        let (now, raised) = w.update(&s);
        assert_eq!(now, raised);
        assert_eq!(raised.len(), 1);
        assert_eq!(
            raised[0].message(),
            "The jaws is 4.0 mm from the structure A"
        );
        assert_eq!(raised[0].time_s, 1.5);
        // Still near: shown, not raised again.
        s.time_s = 1.6;
        s.near[0] = Some(("structure A".into(), 0.003));
        let (now, raised) = w.update(&s);
        assert_eq!((now.len(), raised.len()), (1, 0));
        // Touching and pressing too hard; the beam's force raises nothing.
        s.time_s = 1.7;
        s.touching[0] = true;
        s.force_n = [4.2, 12.0];
        let (_, raised) = w.update(&s);
        let msgs: Vec<String> = raised.iter().map(Alarm::message).collect();
        assert_eq!(
            msgs,
            [
                "The jaws is touching the structure A",
                "The jaws is pressing too hard: 4.2 N"
            ]
        );
        // All clear, then the same force again: a new episode.
        w.update(&status(2.0));
        let mut again = status(2.5);
        again.force_n[0] = 3.6;
        let (_, raised) = w.update(&again);
        assert_eq!(raised.len(), 1);
        // NaN force never alarms (nor passes for a number).
        let mut bad = status(3.0);
        bad.force_n[0] = f32::NAN;
        assert!(w.update(&bad).0.is_empty());
    }
}
