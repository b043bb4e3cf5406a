//! Position-based particles: the cholecystectomy paper's "unified particle" world (its eqs 1-2,
//! after Macklin et al. 2014). Every organ, the fascia and the adhesions are particles with a
//! mass and a body; constraint sets ([`shape`] clusters, [`cloth`] stretch and bending,
//! [`adhesion`] strands, contacts) move the predicted positions until they hold, and the
//! velocities are what the positions did over the step.
//!
//! A step of `dt` (the simulator's 1 ms):
//! 1. [`Particles::predict`]: `x0 = x`, `v += dt (g + F_ext / m)`, `x += dt v`;
//! 2. every constraint set projects `x` (in a fixed order, a fixed number of iterations);
//! 3. [`Particles::finish`]: `v = (x - x0) / dt`, less the point damping `exp(-D dt)`.
//!
//! Units are SI: metres, kilograms (a particle's mass is its tissue's density times the volume
//! it stands for), seconds, newtons. A pinned particle has inverse mass 0.

pub mod adhesion;
pub mod chain;
pub mod cloth;
pub mod colour;
pub mod contacts;
mod device;
pub mod gpu;
pub mod gpu_bench;
mod gpu_schedule;
mod gpu_sets;
pub mod gpu_tools;
pub mod shape;
pub mod solver;

use glam::Vec3;

/// The particles of every body in one world.
#[derive(Debug, Clone, Default)]
pub struct Particles {
    /// Positions, m (predicted during a step).
    pub x: Vec<Vec3>,
    /// Positions at the start of the step, m.
    pub x0: Vec<Vec3>,
    /// Velocities, m/s.
    pub v: Vec<Vec3>,
    /// Inverse masses, 1/kg (0: pinned).
    pub w: Vec<f32>,
    /// Which body each particle belongs to (particles of one body do not collide).
    pub body: Vec<u16>,
    /// Forces for the next step only, N.
    pub ext: Vec<Vec3>,
}

impl Particles {
    pub fn new() -> Particles {
        Particles::default()
    }

    /// Adds a particle at `x` (m) of `mass_kg` (0 or less, or not finite: pinned) in `body`;
    /// returns its index.
    pub fn add(&mut self, x: Vec3, mass_kg: f32, body: u16) -> u32 {
        let w = if mass_kg.is_finite() && mass_kg > 0.0 {
            1.0 / mass_kg
        } else {
            0.0
        };
        self.x.push(x);
        self.x0.push(x);
        self.v.push(Vec3::ZERO);
        self.w.push(w);
        self.body.push(body);
        self.ext.push(Vec3::ZERO);
        (self.x.len() - 1) as u32
    }

    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Heap bytes.
    pub fn heap_bytes(&self) -> usize {
        let v3 = std::mem::size_of::<Vec3>();
        (self.x.capacity() + self.x0.capacity() + self.v.capacity() + self.ext.capacity()) * v3
            + self.w.capacity() * 4
            + self.body.capacity() * 2
    }

    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Mass of particle `i`, kg (infinite when pinned).
    pub fn mass(&self, i: usize) -> f32 {
        match self.w[i] {
            w if w > 0.0 => 1.0 / w,
            _ => f32::INFINITY,
        }
    }

    /// Pins particle `i` where it is (inverse mass 0, at rest).
    pub fn pin(&mut self, i: usize) {
        self.w[i] = 0.0;
        self.v[i] = Vec3::ZERO;
    }

    /// Adds a force on particle `i` for the next step, N (ignored when not finite).
    pub fn add_force(&mut self, i: usize, f: Vec3) {
        if f.is_finite()
            && let Some(e) = self.ext.get_mut(i)
        {
            *e += f;
        }
    }

    /// Step 1: remembers the positions and moves every free particle by its velocity after
    /// gravity and the external forces (which are then used up).
    pub fn predict(&mut self, dt: f32, gravity: Vec3) {
        self.x0.clone_from(&self.x);
        for (((x, v), &w), e) in self
            .x
            .iter_mut()
            .zip(&mut self.v)
            .zip(&self.w)
            .zip(&mut self.ext)
        {
            if w > 0.0 {
                *v += dt * (gravity + *e * w);
                *x += dt * *v;
            }
            *e = Vec3::ZERO;
        }
    }

    /// Step 3: the velocities from what the positions did, less point damping
    /// (`damping_per_s`, 1/s, applied as `exp(-D dt)` so that it does not depend on dt).
    pub fn finish(&mut self, dt: f32, damping_per_s: f32) {
        let keep = (-damping_per_s.max(0.0) * dt).exp();
        let inv = 1.0 / dt;
        for ((v, x), x0) in self.v.iter_mut().zip(&self.x).zip(&self.x0) {
            *v = (*x - *x0) * inv * keep;
        }
    }

    /// Whether every position and velocity is finite.
    pub fn is_finite(&self) -> bool {
        self.x.iter().chain(&self.v).all(|p| p.is_finite())
    }

    /// Kinetic energy, J (pinned particles count nothing).
    pub fn kinetic_energy(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.w)
            .filter(|(_, w)| **w > 0.0)
            .map(|(v, w)| 0.5 * f64::from(v.length_squared()) / f64::from(*w))
            .sum()
    }

    /// A deterministic digest of positions and velocities.
    pub fn state_hash(&self) -> u64 {
        let mut h = crate::sim::Fnv::default();
        for p in self.x.iter().chain(&self.v) {
            for c in p.to_array() {
                h.write(c.to_bits());
            }
        }
        h.0
    }
}

#[cfg(test)]
mod tests;
