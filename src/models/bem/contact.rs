//! Contacts at haptic rate from a precomputation (James and Pai's capacitance method).
//!
//! An instrument holds a set `S` of field elements at displacements it prescribes. Their
//! contact tractions `q_S` (on top of the conditions the problem was precomputed with) follow
//! from the precomputed responses `R` (every unknown's change per pascal on a field element):
//! the contact elements' own rows give the capacitance system `R_SS q_S = target_S - u0_S`
//! (`3|S|` square, at most 192 for 64 contacts), factorised once per contact set and solved
//! every update; the force the tissue takes is `sum_s q_s a_s`, and the whole surface's
//! displacement, for drawing, `Y0 + R_S q_S`.
//!
//! Viscoelasticity (the myotomy paper's Prony parameters): with a Poisson's ratio constant in
//! time, a displacement-controlled contact keeps its displacements and its tractions relax as
//! the relaxation modulus does, `E(t) / E0 = 1 - g1 (1 - exp(-t / tau))`. For any history the
//! contact tractions are `(1 - g1) q_el + g1 h`, where `q_el` is the elastic solution above
//! and `h` its exponentially fading memory, `h' = q_el' - h / tau`, advanced exactly for a
//! `q_el` linear over each step. The surface's displacement under the pressure is kept elastic.

use super::Precomputed;
use super::surface::Element;
use super::system::Factored;
use super::system::{Condition, Known};
use faer::Par;
use glam::DVec3;
use rayon::prelude::*;

/// The one-term Prony series of the relaxation modulus.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prony {
    pub g1: f64,
    pub tau_s: f64,
}

impl Prony {
    /// `E(t) / E0` after a step strain held for `t_s`.
    pub fn relaxation(&self, t_s: f64) -> f64 {
        1.0 - self.g1 * (1.0 - (-t_s / self.tau_s).exp())
    }
}

/// Why a contact set was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContactError {
    #[error("element {element} is not in the precomputed field")]
    NotInField { element: usize },
    #[error("{count} contact elements: at most {most}")]
    TooMany { count: usize, most: usize },
    #[error("{targets} targets for {contacts} contact elements")]
    Targets { targets: usize, contacts: usize },
    #[error("contact element {element} appears twice")]
    Repeated { element: usize },
    #[error("the contact set's capacitance matrix is singular")]
    Singular,
}

impl From<ContactError> for crate::sim::BenchError {
    fn from(e: ContactError) -> Self {
        crate::sim::BenchError::Model(crate::sim::ModelError::new("a contact update", e))
    }
}

/// A contact update worked out but not yet taken: the elastic tractions, the relaxation's
/// memory and the tractions with the relaxation, Pa (3 per contact).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Pending {
    q_el: Vec<f64>,
    memory: Vec<f64>,
    q: Vec<f64>,
}

impl Pending {
    /// Contact `k`'s traction, Pa.
    pub fn traction(&self, k: usize) -> DVec3 {
        match self.q.get(3 * k..3 * k + 3) {
            Some(q) => DVec3::new(q[0], q[1], q[2]),
            None => DVec3::ZERO,
        }
    }
}

/// What of [`Contacts`] changes as they are updated: the set, the tractions and the
/// relaxation's memory (a checkpoint to roll back to; the set's factors are worked out again
/// from the set on a rollback, the same bytes, rather than copied at every checkpoint).
#[derive(Clone, Default)]
pub struct ContactState {
    set: Vec<usize>,
    q_el: Vec<f64>,
    memory: Vec<f64>,
    q: Vec<f64>,
}

/// The most contact elements at once.
pub const MOST_CONTACTS: usize = 64;

/// Contacts against one precomputation.
pub struct Contacts {
    pre: Precomputed,
    /// Each element's slot in the field, if it has one.
    slot: Vec<Option<usize>>,
    areas: Vec<f64>,
    /// The field's own rows of the responses, `3F x 3F` column-major (the capacitance
    /// matrices are gathered from it, not from the whole `N`-row columns).
    rff: Vec<f64>,
    set: Vec<usize>,
    /// The capacitance matrix's factors (of its transpose, as the system keeps them),
    /// factorised on this thread: it is small, and the same bytes on any machine.
    lu: Option<Factored>,
    /// The elastic contact tractions of the last update, Pa (3 per contact), and the fading
    /// memory `h`.
    q_el: Vec<f64>,
    memory: Vec<f64>,
    /// The contact tractions with the relaxation, Pa.
    q: Vec<f64>,
    prony: Option<Prony>,
}

impl Contacts {
    pub fn new(pre: Precomputed, elements: &[Element], prony: Option<Prony>) -> Contacts {
        let mut slot = vec![None; elements.len()];
        for (s, &e) in pre.field.iter().enumerate() {
            if let Some(x) = slot.get_mut(e) {
                *x = Some(s);
            }
        }
        let f3 = 3 * pre.field.len();
        let mut rff = vec![0.0; f3 * f3];
        for col in 0..f3 {
            let column = &pre.response[col * pre.n..(col + 1) * pre.n];
            for (s, &e) in pre.field.iter().enumerate() {
                for c in 0..3 {
                    rff[col * f3 + 3 * s + c] = column.get(3 * e + c).copied().unwrap_or(0.0);
                }
            }
        }
        Contacts {
            pre,
            slot,
            areas: elements.iter().map(|e| e.area_m2).collect(),
            rff,
            set: Vec::new(),
            lu: None,
            q_el: Vec::new(),
            memory: Vec::new(),
            q: Vec::new(),
            prony,
        }
    }

    /// Saves what updates change into `to`, reusing its buffers.
    pub fn save(&self, to: &mut ContactState) {
        to.set.clone_from(&self.set);
        to.q_el.clone_from(&self.q_el);
        to.memory.clone_from(&self.memory);
        to.q.clone_from(&self.q);
    }

    /// Returns to a saved state.
    pub fn load(&mut self, from: &ContactState) {
        if self.set_contacts(&from.set).is_err() {
            // A saved set was a valid one; should it not be, nothing is held.
            self.set.clear();
            self.lu = None;
        }
        self.q_el.clone_from(&from.q_el);
        self.memory.clone_from(&from.memory);
        self.q.clone_from(&from.q);
    }

    /// Adds the contact set and its tractions to a digest.
    pub fn digest(&self, h: &mut crate::sim::Fnv) {
        h.write(self.set.len() as u32);
        for (k, &e) in self.set.iter().enumerate() {
            h.write(e as u32);
            for x in self.traction(k).to_array() {
                let b = x.to_bits();
                h.write(b as u32);
                h.write((b >> 32) as u32);
            }
        }
    }

    /// Whether every traction and the relaxation's memory are finite.
    pub fn is_finite(&self) -> bool {
        self.q
            .iter()
            .chain(&self.q_el)
            .chain(&self.memory)
            .all(|v| v.is_finite())
    }

    /// Puts a NaN into the relaxation's memory and the tractions, where the next update
    /// meets them (fault injection); false when no element is in contact (there is no
    /// state to spoil).
    pub fn inject_nan(&mut self) -> bool {
        let mut spoiled = false;
        for v in [self.memory.first_mut(), self.q.first_mut()]
            .into_iter()
            .flatten()
        {
            *v = f64::NAN;
            spoiled = true;
        }
        spoiled
    }

    pub fn precomputed(&self) -> &Precomputed {
        &self.pre
    }

    /// Whether element `e` can be touched.
    pub fn in_field(&self, e: usize) -> bool {
        self.slot.get(e).is_some_and(Option::is_some)
    }

    /// The elements in contact now.
    pub fn set(&self) -> &[usize] {
        &self.set
    }

    /// The displacement along `rc` of field slot `rs` per pascal along `c` on field slot `s`.
    fn r(&self, rs: usize, rc: usize, s: usize, c: usize) -> f64 {
        self.rff[(3 * s + c) * 3 * self.pre.field.len() + 3 * rs + rc]
    }

    /// Makes `elements` the contact set (factorising its capacitance matrix when it changed;
    /// the relaxation's memory is kept for the elements that stay).
    pub fn set_contacts(&mut self, elements: &[usize]) -> Result<(), ContactError> {
        if elements == self.set.as_slice() {
            return Ok(());
        }
        if elements.len() > MOST_CONTACTS {
            return Err(ContactError::TooMany {
                count: elements.len(),
                most: MOST_CONTACTS,
            });
        }
        let mut slots = Vec::with_capacity(elements.len());
        for (k, &e) in elements.iter().enumerate() {
            if elements[..k].contains(&e) {
                return Err(ContactError::Repeated { element: e });
            }
            match self.slot.get(e).copied().flatten() {
                Some(s) => slots.push(s),
                None => return Err(ContactError::NotInField { element: e }),
            }
        }
        let m = 3 * elements.len();
        // The transpose, column-major: column i holds row i of the capacitance matrix.
        let mut cap_t = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..m {
                cap_t[i * m + j] = self.r(slots[i / 3], i % 3, slots[j / 3], j % 3);
            }
        }
        let mut q_el = vec![0.0; m];
        let mut memory = vec![0.0; m];
        for (k, &e) in elements.iter().enumerate() {
            if let Some(old) = self.set.iter().position(|&x| x == e) {
                q_el[3 * k..3 * k + 3].copy_from_slice(&self.q_el[3 * old..3 * old + 3]);
                memory[3 * k..3 * k + 3].copy_from_slice(&self.memory[3 * old..3 * old + 3]);
            }
        }
        self.lu = if m > 0 {
            Some(Factored::new(m, cap_t, Par::Seq).map_err(|_| ContactError::Singular)?)
        } else {
            None
        };
        self.set = elements.to_vec();
        self.q_el = q_el;
        self.memory = memory;
        self.q = vec![0.0; m];
        Ok(())
    }

    /// Holds the contact elements at `targets` (displacements, m) for a step of `dt_s`:
    /// their contact tractions, and the force the tissue takes from the instrument, N.
    pub fn update(&mut self, targets: &[DVec3], dt_s: f64) -> Result<DVec3, ContactError> {
        let pending = self.preview(targets, dt_s)?;
        Ok(self.commit(pending))
    }

    /// What [`Contacts::update`] would give, the relaxation's memory left as it is (a trial
    /// of a contact set that may change before the step is taken).
    pub fn preview(&self, targets: &[DVec3], dt_s: f64) -> Result<Pending, ContactError> {
        if targets.len() != self.set.len() {
            return Err(ContactError::Targets {
                targets: targets.len(),
                contacts: self.set.len(),
            });
        }
        let m = 3 * self.set.len();
        let Some(lu) = &self.lu else {
            return Ok(Pending::default());
        };
        let mut q_new = vec![0.0; m];
        for (k, (&e, t)) in self.set.iter().zip(targets).enumerate() {
            for c in 0..3 {
                q_new[3 * k + c] = t[c] - self.pre.y0[3 * e + c];
            }
        }
        lu.solve(&mut q_new, 1, Par::Seq);
        let mut memory = self.memory.clone();
        let q = match self.prony {
            Some(p) if dt_s > 0.0 => {
                let x = dt_s / p.tau_s;
                let decay = (-x).exp();
                // For q_el linear over the step: h += (1 - e^-x) / x * dq - (1 - e^-x) h.
                let ramp = if x > 1e-12 { (1.0 - decay) / x } else { 1.0 };
                (0..m)
                    .map(|i| {
                        let dq = q_new[i] - self.q_el[i];
                        memory[i] = decay * memory[i] + ramp * dq;
                        (1.0 - p.g1) * q_new[i] + p.g1 * memory[i]
                    })
                    .collect()
            }
            _ => {
                memory.copy_from_slice(&q_new);
                q_new.clone()
            }
        };
        Ok(Pending {
            q_el: q_new,
            memory,
            q,
        })
    }

    /// Takes the step [`Contacts::preview`] gave (for the contact set it was made with):
    /// the force the tissue takes from the instrument, N.
    pub fn commit(&mut self, pending: Pending) -> DVec3 {
        if pending.q.len() == 3 * self.set.len() {
            self.q_el = pending.q_el;
            self.memory = pending.memory;
            self.q = pending.q;
        }
        self.force_n()
    }

    /// Contact `k`'s traction now (on top of the precomputed conditions), Pa.
    pub fn traction(&self, k: usize) -> DVec3 {
        DVec3::new(self.q[3 * k], self.q[3 * k + 1], self.q[3 * k + 2])
    }

    /// Element `e`'s area, m^2.
    pub fn area(&self, e: usize) -> f64 {
        self.areas.get(e).copied().unwrap_or(0.0)
    }

    /// The force the tissue takes from the instrument now, N (the instrument feels minus it).
    pub fn force_n(&self) -> DVec3 {
        let mut f = DVec3::ZERO;
        for (k, &e) in self.set.iter().enumerate() {
            let q = DVec3::new(self.q[3 * k], self.q[3 * k + 1], self.q[3 * k + 2]);
            f += q * self.areas[e];
        }
        f
    }

    /// Every element's displacement now, m (the elastic field: under displacement control
    /// the relaxation changes the forces, not the shape), given the conditions the
    /// precomputation was made with.
    pub fn displacements(&self, conditions: &[Condition], out: &mut Vec<DVec3>) {
        let n = self.pre.n;
        let mut y = self.pre.y0.clone();
        // (response column, traction) of every held element's components, in order.
        let terms: Vec<(usize, f64)> = self
            .set
            .iter()
            .enumerate()
            .flat_map(|(k, &e)| {
                let s = self.slot[e];
                (0..3).filter_map(move |c| s.map(|s| (3 * s + c, k, c)))
            })
            .map(|(col, k, c)| (col, self.q_el[3 * k + c]))
            .filter(|&(_, q)| q != 0.0)
            .collect();
        // Rows in parallel, each summing the terms in the same order: the same bytes on any
        // number of threads.
        let response = &self.pre.response;
        y.par_chunks_mut(1024).enumerate().for_each(|(b, rows)| {
            let from = b * 1024;
            for &(col, q) in &terms {
                let column = &response[col * n + from..col * n + from + rows.len()];
                for (yi, ri) in rows.iter_mut().zip(column) {
                    *yi += ri * q;
                }
            }
        });
        out.clear();
        out.extend(y.chunks_exact(3).zip(conditions).map(|(v, cond)| {
            let mut u = DVec3::ZERO;
            for c in 0..3 {
                u[c] = match cond.known[c] {
                    Known::Displacement => cond.value[c],
                    Known::Traction => v[c],
                };
            }
            u
        }));
    }
}

#[cfg(test)]
#[path = "contact_tests.rs"]
mod tests;
