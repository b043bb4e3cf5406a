//! The guidewire: a thin chain of skeleton balls run inside the catheter's lumen, fed and
//! turned on its own. Its bending is the same angle springs as the catheter's, set from the
//! wire's flexural rigidity `EI` (a discretised rod: `k_t = EI / lambda` at each inner ball
//! `lambda` apart), stiff along its core and soft over its distal tip, which rests straight
//! or curved into a J (a shapeable tip, curved at rest through `j_angle_deg` over its soft
//! part, in the plane the wire's twist turns). Guidewires carry torque almost one to one, so
//! the tip's plane is the handle's twist, without the catheter's torsion dynamics.
//!
//! Inside the catheter the lumen holds the wire on the catheter's axis ([`coaxial`]): each
//! wire ball inside is pulled towards the nearest point of the catheter's centreline, and
//! the two balls of that segment take the opposite force, split by where the point lies.
//! Along the axis the wire slides freely (a lubricious coating). Held together, the two bend
//! as one rod whose rigidity is the sum of theirs; past the catheter's tip the wire leads
//! on its own.
//!
//! Material figures are ours (the catheter paper has no guidewire): a nitinol core of
//! 6,450 kg/m^3 in a 0.9 mm (0.035 in) wire, `EI` of the order of a diagnostic wire's.

use super::catheter::{Catheter, Drive};
use super::tree::nearest_segment;
use super::{AngleSpring, Balls, LinearSpring, Rod, add_angle_forces, add_spring_forces};
use glam::{DQuat, DVec3};

/// The wire's size and materials.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidewireParams {
    pub length_m: f64,
    pub diameter_m: f64,
    pub density_kg_per_m3: f64,
    /// The balls' spacing along the wire, m.
    pub spacing_m: f64,
    /// Each segment's axial spring, N/m, and the springs' damping, N/(m/s).
    pub axial_n_per_m: f64,
    pub damping_n_s_per_m: f64,
    /// Flexural rigidity of the core and of the soft tip, N m^2.
    pub core_ei_n_m2: f64,
    pub tip_ei_n_m2: f64,
    /// The soft tip's length, m, and its curve at rest (0: straight; a J at 90 to 180).
    pub tip_length_m: f64,
    pub j_angle_deg: f64,
    /// The lumen's hold on each wire ball inside the catheter, N/m, and its damping.
    pub lumen_n_per_m: f64,
    pub lumen_damping_n_s_per_m: f64,
}

impl Default for GuidewireParams {
    fn default() -> Self {
        GuidewireParams {
            length_m: 0.150,
            diameter_m: 0.0009,
            density_kg_per_m3: 6450.0,
            spacing_m: 0.005,
            axial_n_per_m: 100.0,
            damping_n_s_per_m: 0.002,
            core_ei_n_m2: 2.0e-5,
            tip_ei_n_m2: 2.0e-6,
            tip_length_m: 0.020,
            j_angle_deg: 0.0,
            lumen_n_per_m: 50.0,
            lumen_damping_n_s_per_m: 0.002,
        }
    }
}

/// What the hand asks of the wire this step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WireDrive {
    /// How far the wire's tip is past the entry along its axis when straight, m.
    pub insertion_m: f64,
    /// The handle's twist, rad: the tip's curve turns with it.
    pub twist_rad: f64,
}

/// Each joint's damping as a share of the core joint's `sqrt(k_t m lambda^2)` (a twentieth
/// of its critical damping): a ball feels up to three joints' damping, some 16 times one
/// joint's in a zig-zag, which the explicit substep must stay well within (a quarter of
/// critical was unstable on the core at 0.1 ms). The soft tip's joints get the core's
/// coefficient, stable as the core's: a larger share of their own critical damping (a third
/// of it for a tip ten times softer), which calms the tip's swing where the lumen holds a
/// curved tip straight (the catheter coming over it).
pub const JOINT_DAMPING: f64 = 0.1;

/// The fastest the wire's handle follows the hand, m/s.
pub const WIRE_HANDLE_M_PER_S: f64 = 0.5;

/// The guidewire: balls (0 at the handle, the last the tip), springs and where it enters.
#[derive(Debug, Clone, PartialEq)]
pub struct Guidewire {
    pub balls: Balls,
    pub springs: Vec<LinearSpring>,
    pub angles: Vec<AngleSpring>,
    pub entry: DVec3,
    pub axis: DVec3,
    /// The balls of the soft tip (the last ones).
    pub tip_balls: usize,
    pub params: GuidewireParams,
}

impl Guidewire {
    /// A straight wire along `axis` with its tip at `entry` (all of it behind the entry).
    pub fn new(p: &GuidewireParams, entry: DVec3, axis: DVec3) -> Guidewire {
        let axis = axis.normalize_or(DVec3::X);
        let r = 0.5 * p.diameter_m;
        let n = ((p.length_m / p.spacing_m).round() as usize + 1).max(3);
        let spacing = p.length_m / (n - 1) as f64;
        let rod = Rod {
            length_m: p.length_m,
            radius_m: r,
            density_kg_per_m3: p.density_kg_per_m3,
            n,
        };
        let (balls, springs) = rod.chain(entry, axis, p.axial_n_per_m, p.damping_n_s_per_m);
        let tip_balls = ((p.tip_length_m / spacing).round() as usize + 1).clamp(2, n);
        let angles = (1..n - 1)
            .map(|i| {
                let ei = if i >= n - tip_balls {
                    p.tip_ei_n_m2
                } else {
                    p.core_ei_n_m2
                };
                let k_t = ei / spacing;
                // The core's coefficient at every joint (see JOINT_DAMPING).
                let m = balls.mass_kg[i];
                let core_k_t = p.core_ei_n_m2 / spacing;
                AngleSpring {
                    prev: i as u32 - 1,
                    mid: i as u32,
                    next: i as u32 + 1,
                    stiffness_n_m_per_rad: k_t,
                    damping_n_m_s_per_rad: JOINT_DAMPING
                        * (core_k_t * m * spacing * spacing).sqrt(),
                    rest_turn: DVec3::ZERO,
                }
            })
            .collect();
        Guidewire {
            balls,
            springs,
            angles,
            entry,
            axis,
            tip_balls,
            params: *p,
        }
    }

    /// The same wire moved along its axis so that its tip is `insertion_m` past the entry.
    pub fn inserted(mut self, insertion_m: f64) -> Guidewire {
        let d = self.axis * insertion_m;
        self.balls.x.iter_mut().for_each(|x| *x += d);
        self.balls.hold_behind(self.entry, self.axis);
        self
    }

    pub fn tip(&self) -> DVec3 {
        self.balls.x[self.balls.len() - 1]
    }

    /// The first ball past the entry (those before are in the introducer).
    pub fn first_inside(&self) -> usize {
        self.balls
            .x
            .iter()
            .position(|x| (*x - self.entry).dot(self.axis) >= 0.0)
            .unwrap_or(self.balls.len())
    }

    /// The rest turns of the soft tip for the J curve in the plane turned by `twist_rad`
    /// about the wire's own direction: once a step.
    pub fn orient(&mut self, twist_rad: f64) {
        let n = self.balls.len();
        let first = n - self.tip_balls;
        let joints = (self.tip_balls - 1).max(1) as f64;
        let per_joint = self.params.j_angle_deg.to_radians() / joints;
        let across = super::catheter::any_across(self.axis);
        for s in &mut self.angles {
            let mid = s.mid as usize;
            if mid < first || per_joint == 0.0 {
                s.rest_turn = DVec3::ZERO;
                continue;
            }
            let e1 = (self.balls.x[mid] - self.balls.x[s.prev as usize]).normalize_or(self.axis);
            // The curve's side: the entry's "up" turned by the twist, carried onto this arm.
            let up = DQuat::from_axis_angle(self.axis, twist_rad) * across;
            let up = (up - e1 * e1.dot(up)).normalize_or(across);
            s.rest_turn = e1.cross(up).normalize_or_zero() * per_joint;
        }
    }

    /// The handle's place for the drive, moved at most [`WIRE_HANDLE_M_PER_S`] over `dt_s`,
    /// and the speed that takes it there.
    fn handle(&self, drive: &WireDrive, dt_s: f64) -> (DVec3, DVec3) {
        let want = self.entry + self.axis * (drive.insertion_m - self.params.length_m);
        let step = (want - self.balls.x[0]).clamp_length_max(WIRE_HANDLE_M_PER_S * dt_s);
        (self.balls.x[0] + step, step / dt_s.max(1e-12))
    }

    /// The wire's own forces for a substep: the handle moved by the drive, the given
    /// external forces (the wall's), its springs and its bending.
    fn gather(&mut self, drive: &WireDrive, external: &[DVec3], dt_s: f64) {
        let (handle, _) = self.handle(drive, dt_s);
        self.balls.x[0] = handle;
        self.balls.start_forces(DVec3::ZERO);
        for (f, e) in self.balls.f.iter_mut().zip(external) {
            *f += *e;
        }
        add_spring_forces(&mut self.balls, &self.springs);
        add_angle_forces(&mut self.balls, &self.angles);
    }

    /// Moves the balls under the gathered forces; behind the entry they are held on its
    /// axis (the introducer), the handle moves at `handle_speed`.
    fn advance(&mut self, dt_s: f64, handle_speed: DVec3) {
        self.balls.integrate(dt_s);
        self.balls.v[0] = handle_speed;
        self.balls.hold_behind(self.entry, self.axis);
    }

    /// One substep under the given external forces (the wall's, the lumen's): the tip's
    /// rest curve turned to the drive's twist where the wire is now (every substep: a curve
    /// set from where the wire was a whole step ago lags it, and a lagging follower pumps
    /// energy into the soft tip's swing), then its forces gathered and the balls moved.
    pub fn step(&mut self, drive: &WireDrive, external: &[DVec3], dt_s: f64) {
        if self.params.j_angle_deg != 0.0 {
            self.orient(drive.twist_rad);
        }
        let (_, speed) = self.handle(drive, dt_s);
        self.gather(drive, external, dt_s);
        self.advance(dt_s, speed);
    }
}

/// One substep of the catheter with the wire in its lumen: the lumen's hold ([`coaxial`],
/// within the catheter's radius of its axis) from where both are now joins each one's wall
/// contact, then both take their substep. The world's coupling
/// ([`super::wall::WallContact`]) does the same between the two models. Returns how many
/// wire balls are held.
pub fn step_together(
    catheter: &mut Catheter,
    (drive, contact): (&Drive, &[DVec3]),
    wire: &mut Guidewire,
    (wire_drive, wire_contact): (&WireDrive, &[DVec3]),
    dt_s: f64,
) -> usize {
    let mut on_catheter = contact.to_vec();
    let mut on_wire = wire_contact.to_vec();
    let held = lumen(catheter, wire, &mut on_wire, &mut on_catheter);
    catheter.step(drive, &on_catheter, dt_s);
    wire.step(wire_drive, &on_wire, dt_s);
    held
}

/// The lumen's forces between `catheter` and the `wire` in it, added to `on_wire` and
/// `on_catheter` (per ball): [`coaxial`] with the wire's lumen stiffness and damping within
/// the catheter's radius. Returns how many wire balls are held.
pub fn lumen(
    catheter: &Catheter,
    wire: &Guidewire,
    on_wire: &mut [DVec3],
    on_catheter: &mut [DVec3],
) -> usize {
    let p = wire.params;
    coaxial(
        (&wire.balls, on_wire),
        (&catheter.balls, on_catheter),
        (p.lumen_n_per_m, p.lumen_damping_n_s_per_m),
        0.5 * catheter.params.diameter_m,
    )
}

/// Which of the wire's balls lie inside the catheter (their nearest point on its centreline
/// not past the tip nor before the handle, within the catheter's radius): the catheter
/// shields them from the wall, so the wall's collision leaves them out.
pub fn shielded(catheter: &Catheter, wire: &Guidewire) -> Vec<bool> {
    let reach = 0.5 * catheter.params.diameter_m;
    let segments = catheter.balls.len().saturating_sub(1);
    wire.balls
        .x
        .iter()
        .map(|&x| {
            nearest_segment(&catheter.balls.x, x).is_some_and(|(j, t, dist2)| {
                let past_tip = j + 1 == segments && t > 1.0;
                let before_handle = j == 0 && t < 0.0;
                !past_tip && !before_handle && dist2 < reach * reach
            })
        })
        .collect()
}

/// How far past the catheter's tip the lumen's mouth still guides a wire ball, in segments:
/// the hold fades from full at the tip to none this far out, so that a wire ball leaving or
/// entering the catheter meets no jump in force.
pub const MOUTH_SEGMENTS: f64 = 0.5;

/// The lumen's hold: each of `wire`'s balls that lies within the catheter (its nearest point
/// on the catheter's centreline `tube` falls inside a segment, or on the last one's line
/// up to [`MOUTH_SEGMENTS`] past the tip, within `reach_m` of it) is pulled towards that
/// point across the segment (`k` N/m, `c` N s/m on the relative speed across it), and the
/// segment's two balls take the opposite force, shared as the point divides the segment (a
/// lever past the tip). The hold is full within half of `reach_m` of the axis and inside
/// the tip; beyond, it fades to nothing at `reach_m` across and at the mouth's end (a ball
/// the catheter comes over is taken in without a jolt). The forces are added to `on_wire`
/// and `on_tube` (per ball), in index order; one that is not finite (from a chain gone bad,
/// which its world rolls back) is dropped, so the other chain stays good. Returns how many
/// wire balls are held.
pub fn coaxial(
    (wire, on_wire): (&Balls, &mut [DVec3]),
    (tube, on_tube): (&Balls, &mut [DVec3]),
    (k, c): (f64, f64),
    reach_m: f64,
) -> usize {
    let segments = tube.len().saturating_sub(1);
    let full_m = 0.5 * reach_m;
    let mut held = 0;
    for i in 0..wire.len() {
        if wire.fixed[i] {
            continue;
        }
        let x = wire.x[i];
        let Some((j, t, dist2)) = nearest_segment(&tube.x, x) else {
            continue;
        };
        let last = j + 1 == segments;
        let beyond = if last { (t - 1.0).max(0.0) } else { 0.0 };
        // Outside the lumen: past the mouth, before the first ball, or too far across.
        if beyond >= MOUTH_SEGMENTS || (j == 0 && t < 0.0) || dist2 >= reach_m * reach_m {
            continue;
        }
        // The point on the segment (on its line past the tip).
        let t = if last { t.max(0.0) } else { t.clamp(0.0, 1.0) };
        let (a, b) = (j, j + 1);
        let axis = (tube.x[b] - tube.x[a]).normalize_or_zero();
        let p = tube.x[a] + (tube.x[b] - tube.x[a]) * t;
        let vp = tube.v[a] + (tube.v[b] - tube.v[a]) * t;
        let across = |v: DVec3| v - axis * axis.dot(v);
        let off = across(p - x);
        let d = off.length();
        let fade_across = if d <= full_m {
            1.0
        } else {
            full_m * (reach_m - d) / ((reach_m - full_m) * d)
        };
        let fade_mouth = 1.0 - beyond / MOUTH_SEGMENTS;
        let f = (off * k * fade_across + across(vp - wire.v[i]) * c) * fade_mouth;
        if !f.is_finite() {
            // A chain gone non-finite (its world rolls it back) passes nothing to the other.
            continue;
        }
        on_wire[i] += f;
        on_tube[a] -= f * (1.0 - t);
        on_tube[b] -= f * t;
        held += 1;
    }
    held
}

#[cfg(test)]
#[path = "guidewire_tests.rs"]
mod tests;
