//! Attachments: points of one model tied to points of another by springs (a vessel entering
//! an organ, a membrane on a rod, a ligament to its bed). Each tie is a spring-damper along
//! the line between its two points; it tears, once, when its force passes a limit.

use super::EventKind;
use super::world::{Interaction, ModelId, PointForces, PointSource};
use glam::Vec3;

/// One tie between point `a` of model `from` and point `b` of model `to`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Link {
    pub a: u32,
    pub b: u32,
    /// Rest length, metres.
    pub rest_m: f32,
}

/// The spring-damper every link of an attachment shares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkSpring {
    /// Stiffness, N/m.
    pub stiffness_n_per_m: f32,
    /// Damping along the link, N s/m.
    pub damping_n_s_per_m: f32,
    /// A link tears above this force, N (infinite: never).
    pub break_force_n: f32,
}

/// Links from one model's points to another's, applied as equal and opposite forces.
#[derive(Debug, Clone)]
pub struct Attachment {
    name: String,
    from: ModelId,
    to: ModelId,
    spring: LinkSpring,
    links: Vec<Link>,
    /// Length of each link after the last step (for damping); none before the first.
    last_len: Vec<Option<f32>>,
    alive: Vec<bool>,
    /// The force each link pulled `from`'s point with in the last step, newtons.
    forces: Vec<Vec3>,
}

impl Attachment {
    pub fn new(
        name: &str,
        from: ModelId,
        to: ModelId,
        spring: LinkSpring,
        links: Vec<Link>,
    ) -> Self {
        let n = links.len();
        Self {
            name: name.to_string(),
            from,
            to,
            spring,
            links,
            last_len: vec![None; n],
            alive: vec![true; n],
            forces: vec![Vec3::ZERO; n],
        }
    }

    pub fn links(&self) -> &[Link] {
        &self.links
    }

    /// Links still holding.
    pub fn holding(&self) -> usize {
        self.alive.iter().filter(|a| **a).count()
    }

    /// The total force the attachment put on the `from` model in the last step, newtons (the
    /// `to` model got the opposite).
    pub fn total_force(&self) -> Vec3 {
        self.forces.iter().copied().sum()
    }
}

impl Interaction for Attachment {
    fn name(&self) -> &str {
        &self.name
    }

    fn apply(
        &mut self,
        dt_s: f32,
        points: &dyn PointSource,
        forces: &mut PointForces,
        events: &mut Vec<EventKind>,
    ) {
        let s = self.spring;
        for (k, link) in self.links.iter().enumerate() {
            self.forces[k] = Vec3::ZERO;
            if !self.alive[k] {
                continue;
            }
            let (Some(pa), Some(pb)) = (
                points.point(self.from, link.a),
                points.point(self.to, link.b),
            ) else {
                // One end was cut away: the link goes with it.
                self.alive[k] = false;
                continue;
            };
            let d = pb - pa;
            let len = d.length();
            let dir = if len > 1e-12 { d / len } else { Vec3::ZERO };
            let rate = self.last_len[k].map_or(0.0, |l| (len - l) / dt_s);
            self.last_len[k] = Some(len);
            let magnitude = s.stiffness_n_per_m * (len - link.rest_m) + s.damping_n_s_per_m * rate;
            if magnitude.abs() > s.break_force_n {
                self.alive[k] = false;
                events.push(EventKind::Rupture {
                    what: self.name.clone(),
                    models: [
                        points.name(self.from).to_string(),
                        points.name(self.to).to_string(),
                    ],
                    force_n: magnitude.abs(),
                });
                continue;
            }
            let f = dir * magnitude;
            self.forces[k] = f;
            forces.add(self.from, link.a, f);
            forces.add(self.to, link.b, -f);
        }
    }
}
