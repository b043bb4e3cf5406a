//! What the renderer draws of the cholecystectomy: each organ's skin (the outer faces of the
//! lattice cubes whose eight corners are its particles, so the skin moves with them, drawn
//! smoothed so the lattice's steps do not show), the vessels and the strands as thin tubes
//! along their intact segments, the fascia's intact triangles.

use crate::models::particles::Particles;
use crate::sim::{ModelSnapshot, SurfaceRole};
use glam::{IVec3, Vec3};
use std::collections::{HashMap, HashSet};

/// An organ's skin: triangles over particle indices, wound outwards at rest.
#[derive(Debug, Clone, Default)]
pub struct Skin {
    /// The particles the skin uses, and its triangles as indices into them.
    pub particles: Vec<u32>,
    pub triangles: Vec<u32>,
    /// Each skin vertex's neighbours along the triangles' edges: those of vertex `v` are
    /// `ring[ring_start[v]..ring_start[v + 1]]`.
    pub ring_start: Vec<u32>,
    pub ring: Vec<u32>,
    /// The drawn skin at rest: each vertex's offset from its particle to the smoothed skin,
    /// the stepped surface's frame there, and the smoothed skin's normal (see [`skin_mesh`]).
    pub offsets: Vec<Vec3>,
    pub rest_frames: Vec<glam::Quat>,
    pub smooth_normals: Vec<Vec3>,
}

/// Taubin's filter on the skin at rest: passes of a shrinking step (`LAMBDA`) then an
/// inflating one (`MU`), which smooths the lattice's steps (a few cells long) without shrinking
/// the organ.
const SMOOTH_PASSES: usize = 20;
const LAMBDA: f32 = 0.5;
const MU: f32 = -0.53;

impl Skin {
    /// Fills the neighbour rings from the triangles.
    fn link(&mut self) {
        let n = self.particles.len();
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(2 * self.triangles.len());
        for t in self.triangles.chunks_exact(3) {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                pairs.push((a, b));
                pairs.push((b, a));
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        self.ring_start = vec![0; n + 1];
        for &(a, _) in &pairs {
            self.ring_start[a as usize + 1] += 1;
        }
        for v in 0..n {
            self.ring_start[v + 1] += self.ring_start[v];
        }
        self.ring = pairs.into_iter().map(|(_, b)| b).collect();
    }

    /// The stepped surface's frame at each vertex of `positions` (normals `normals`): the
    /// normal, and across it the direction to the vertex's first neighbour.
    fn frames(&self, positions: &[Vec3], normals: &[Vec3]) -> Vec<glam::Quat> {
        positions
            .iter()
            .zip(normals)
            .enumerate()
            .map(|(v, (&x, &n))| {
                let first = self.ring.get(self.ring_start[v] as usize);
                let to = first.map_or(Vec3::ZERO, |&u| positions[u as usize] - x);
                let t = (to - n * to.dot(n)).normalize_or(n.any_orthonormal_vector());
                glam::Quat::from_mat3(&glam::Mat3::from_cols(t, n.cross(t), n))
            })
            .collect()
    }

    /// `positions` (one per skin vertex) smoothed along the skin.
    pub fn smooth(&self, positions: &mut Vec<Vec3>) {
        let mut next = positions.clone();
        for _ in 0..SMOOTH_PASSES {
            for w in [LAMBDA, MU] {
                for (v, out) in next.iter_mut().enumerate() {
                    let (a, b) = (self.ring_start[v] as usize, self.ring_start[v + 1] as usize);
                    let p = positions[v];
                    *out = if b > a {
                        let mean = self.ring[a..b]
                            .iter()
                            .map(|&u| positions[u as usize])
                            .sum::<Vec3>()
                            / (b - a) as f32;
                        p + (mean - p) * w
                    } else {
                        p
                    };
                }
                std::mem::swap(positions, &mut next);
            }
        }
    }
}

/// The skin of the lattice particles `members` (rest positions `x`, spacing `h`): every face
/// of a full lattice cube (all eight corners members) that no other full cube shares.
pub fn lattice_skin(x: &[Vec3], members: &[u32], h: f32) -> Skin {
    let Some(&first) = members.first() else {
        return Skin::default();
    };
    let origin = x[first as usize];
    let cell_of = |p: Vec3| ((p - origin) / h).round().as_ivec3();
    let at: HashMap<IVec3, u32> = members
        .iter()
        .map(|&i| (cell_of(x[i as usize]), i))
        .collect();
    let corner = |c: IVec3, d: [i32; 3]| at.get(&(c + IVec3::from(d))).copied();
    let full: HashSet<IVec3> = at
        .keys()
        .copied()
        .filter(|&c| (0..8).all(|k| corner(c, [k & 1, (k >> 1) & 1, (k >> 2) & 1]).is_some()))
        .collect();
    let mut cubes: Vec<IVec3> = full.iter().copied().collect();
    cubes.sort_by_key(|c| (c.x, c.y, c.z));
    // Each face: the neighbour's offset and its four corners in order around it.
    const FACES: [([i32; 3], [[i32; 3]; 4]); 6] = [
        ([-1, 0, 0], [[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]]),
        ([1, 0, 0], [[1, 0, 0], [1, 0, 1], [1, 1, 1], [1, 1, 0]]),
        ([0, -1, 0], [[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0]]),
        ([0, 1, 0], [[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]]),
        ([0, 0, -1], [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]),
        ([0, 0, 1], [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]]),
    ];
    let mut used: HashMap<u32, u32> = HashMap::new();
    let mut skin = Skin::default();
    for c in cubes {
        for (off, quad) in FACES {
            if full.contains(&(c + IVec3::from(off))) {
                continue;
            }
            let q = quad.map(|d| corner(c, d).unwrap_or(first));
            // Wound so the face's normal points out of the cube.
            let (a, b, d) = (x[q[0] as usize], x[q[1] as usize], x[q[3] as usize]);
            let outward = Vec3::new(off[0] as f32, off[1] as f32, off[2] as f32);
            let order = if (b - a).cross(d - a).dot(outward) > 0.0 {
                [q[0], q[1], q[2], q[0], q[2], q[3]]
            } else {
                [q[0], q[2], q[1], q[0], q[3], q[2]]
            };
            for i in order {
                let next = used.len() as u32;
                let v = *used.entry(i).or_insert_with(|| {
                    skin.particles.push(i);
                    next
                });
                skin.triangles.push(v);
            }
        }
    }
    skin.link();
    let rest: Vec<Vec3> = skin.particles.iter().map(|&i| x[i as usize]).collect();
    let mut smooth = rest.clone();
    skin.smooth(&mut smooth);
    let stepped = crate::mesh::vertex_normals(&rest, &skin.triangles);
    skin.rest_frames = skin.frames(&rest, &stepped);
    skin.smooth_normals = crate::mesh::vertex_normals(&smooth, &skin.triangles);
    skin.offsets = smooth.iter().zip(&rest).map(|(s, r)| *s - *r).collect();
    skin
}

/// The skin drawn at the particles' present places, smoothed: each vertex is its particle
/// plus its offset to the smoothed skin at rest, turned as the stepped surface's frame there
/// (its normal and the way to a neighbour) has turned since, and its normal the smoothed one
/// turned the same way. One pass over the triangles, not a filter's
/// twenty over the skin each frame; the skin moves, bends and turns with its particles.
pub fn skin_mesh(p: &Particles, skin: &Skin, name: &str, role: SurfaceRole) -> ModelSnapshot {
    let mut positions: Vec<Vec3> = skin.particles.iter().map(|&i| p.x[i as usize]).collect();
    let stepped = crate::mesh::vertex_normals(&positions, &skin.triangles);
    let frames = skin.frames(&positions, &stepped);
    let mut normals = Vec::with_capacity(positions.len());
    for (v, (x, (n, now))) in positions
        .iter_mut()
        .zip(stepped.into_iter().zip(frames))
        .enumerate()
    {
        let (Some(&offset), Some(&rest), Some(&smooth)) = (
            skin.offsets.get(v),
            skin.rest_frames.get(v),
            skin.smooth_normals.get(v),
        ) else {
            normals.push(n);
            continue;
        };
        let turn = now * rest.inverse();
        *x += turn * offset;
        normals.push(turn * smooth);
    }
    ModelSnapshot {
        seared: Vec::new(),
        name: name.to_string(),
        cut_edge: vec![false; positions.len()],
        regions: vec![0; skin.triangles.len() / 3],
        roles: vec![role],
        positions,
        normals,
        indices: skin.triangles.clone(),
    }
}

/// Sides of a drawn tube.
const TUBE_SIDES: usize = 6;

/// Tubes of `radius_m` along segments (particle pairs) of `p`, each with its region; `roles`
/// gives each region's role.
pub fn tubes(
    p: &Particles,
    segments: impl Iterator<Item = ((u32, u32), u8, f32)>,
    name: &str,
    roles: Vec<SurfaceRole>,
) -> ModelSnapshot {
    let mut m = ModelSnapshot {
        name: name.to_string(),
        roles,
        ..ModelSnapshot::default()
    };
    for ((a, b), region, radius) in segments {
        let (xa, xb) = (p.x[a as usize], p.x[b as usize]);
        let Some(axis) = (xb - xa).try_normalize() else {
            continue;
        };
        let u = axis.any_orthonormal_vector();
        let v = axis.cross(u);
        let base = m.positions.len() as u32;
        for k in 0..TUBE_SIDES {
            let t = std::f32::consts::TAU * k as f32 / TUBE_SIDES as f32;
            let n = u * t.cos() + v * t.sin();
            for end in [xa, xb] {
                m.positions.push(end + n * radius);
                m.normals.push(n);
                m.cut_edge.push(false);
            }
        }
        for k in 0..TUBE_SIDES as u32 {
            let (i0, i1) = (base + 2 * k, base + 2 * ((k + 1) % TUBE_SIDES as u32));
            m.indices.extend([i0, i0 + 1, i1, i1, i0 + 1, i1 + 1]);
            m.regions.extend([region, region]);
        }
    }
    m
}

/// The fascia's triangles whose three edges are still intact (`alive`: the intact edges as
/// ordered pairs), both faces drawn.
pub fn fascia_mesh(
    p: &Particles,
    triangles: &[[u32; 3]],
    alive: &HashSet<(u32, u32)>,
) -> ModelSnapshot {
    let edge = |a: u32, b: u32| alive.contains(&(a.min(b), a.max(b)));
    let mut m = ModelSnapshot {
        name: "fascia".to_string(),
        roles: vec![SurfaceRole::Membrane],
        ..ModelSnapshot::default()
    };
    let mut index: HashMap<u32, u32> = HashMap::new();
    for t in triangles {
        if !(edge(t[0], t[1]) && edge(t[1], t[2]) && edge(t[2], t[0])) {
            continue;
        }
        for i in [t[0], t[1], t[2]] {
            let next = index.len() as u32;
            let v = *index.entry(i).or_insert_with(|| {
                m.positions.push(p.x[i as usize]);
                next
            });
            m.indices.push(v);
        }
        m.regions.push(0);
    }
    m.normals = crate::mesh::vertex_normals(&m.positions, &m.indices);
    m.cut_edge = vec![false; m.positions.len()];
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_block_of_lattice_points_is_skinned_by_its_outer_faces_wound_outwards() {
        // A 3 x 3 x 3 block (2 x 2 x 2 cubes): 6 sides of 4 faces, 2 triangles each.
        let h = 0.01;
        let mut x = Vec::new();
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    x.push(Vec3::new(i as f32, j as f32, k as f32) * h);
                }
            }
        }
        let members: Vec<u32> = (0..27).collect();
        let s = lattice_skin(&x, &members, h);
        assert_eq!(s.triangles.len() / 3, 6 * 4 * 2);
        // Every point but the centre is on the skin.
        assert_eq!(s.particles.len(), 26);
        let centre = Vec3::splat(h);
        for t in s.triangles.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|k| x[s.particles[k as usize] as usize]);
            let n = (b - a).cross(c - a);
            assert!(n.dot((a + b + c) / 3.0 - centre) > 0.0, "inward face");
        }
    }

    #[test]
    fn a_lattice_balls_drawn_skin_is_round_not_stepped() {
        // A ball of radius 10 spacings on the lattice.
        let (h, radius) = (0.0035f32, 0.035f32);
        let mut x = Vec::new();
        let n = (radius / h).ceil() as i32 + 1;
        for i in -n..=n {
            for j in -n..=n {
                for k in -n..=n {
                    let p = Vec3::new(i as f32, j as f32, k as f32) * h;
                    if p.length() <= radius {
                        x.push(p);
                    }
                }
            }
        }
        let members: Vec<u32> = (0..x.len() as u32).collect();
        let skin = lattice_skin(&x, &members, h);
        let mut p = Particles::new();
        for &q in &x {
            p.add(q, 1.0, 0);
        }
        let raw: Vec<Vec3> = skin.particles.iter().map(|&i| x[i as usize]).collect();
        let drawn = skin_mesh(&p, &skin, "ball", SurfaceRole::Tissue);
        // How far the normals turn from the radial direction, and how far the points lie
        // from the mean radius.
        let worst_turn = |pos: &[Vec3], normals: &[Vec3]| {
            pos.iter()
                .zip(normals)
                .map(|(q, n)| n.angle_between(q.normalize()).to_degrees())
                .fold(0.0f32, f32::max)
        };
        let spread = |pos: &[Vec3]| {
            let mean = pos.iter().map(|q| q.length()).sum::<f32>() / pos.len() as f32;
            let sd = (pos.iter().map(|q| (q.length() - mean).powi(2)).sum::<f32>()
                / pos.len() as f32)
                .sqrt();
            (mean, sd)
        };
        let raw_normals = crate::mesh::vertex_normals(&raw, &skin.triangles);
        let (raw_turn, drawn_turn) = (
            worst_turn(&raw, &raw_normals),
            worst_turn(&drawn.positions, &drawn.normals),
        );
        let ((raw_mean, raw_sd), (mean, sd)) = (spread(&raw), spread(&drawn.positions));
        eprintln!(
            "turn {raw_turn} -> {drawn_turn}, radius {raw_mean} +- {raw_sd} -> {mean} +- {sd}"
        );
        assert!(
            raw_turn > 40.0,
            "the raw steps turn normals {raw_turn} degrees"
        );
        assert!(
            drawn_turn < 15.0,
            "smoothed, normals turn {drawn_turn} degrees"
        );
        assert!(sd < 0.4 * raw_sd, "radius spread {raw_sd} -> {sd} m");
        // Not shrunk: the mean radius moves by less than a fifth of a spacing.
        assert!((mean - raw_mean).abs() < 0.2 * h, "{raw_mean} -> {mean} m");
        // Turned and moved as a whole, the drawn skin turns and moves with it.
        let q = glam::Quat::from_euler(glam::EulerRot::XYZ, 0.4, -0.7, 1.1);
        let shift = Vec3::new(0.02, -0.01, 0.05);
        for (k, &r) in x.iter().enumerate() {
            p.x[k] = q * r + shift;
        }
        let moved = skin_mesh(&p, &skin, "ball", SurfaceRole::Tissue);
        for (a, b) in drawn.positions.iter().zip(&moved.positions) {
            assert!(
                (q * *a + shift).distance(*b) < 1e-5,
                "{a} -> {b}, expected {}",
                q * *a + shift
            );
        }
        for (a, b) in drawn.normals.iter().zip(&moved.normals) {
            assert!((q * *a).dot(*b) > 1.0 - 1e-4);
        }
    }

    #[test]
    fn fascia_triangles_with_a_cut_edge_are_not_drawn() {
        let mut p = Particles::new();
        for x in [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE] {
            p.add(x, 1.0, 0);
        }
        let tris = [[0, 1, 2], [1, 3, 2]];
        let mut alive: HashSet<(u32, u32)> = [(0, 1), (1, 2), (0, 2), (1, 3), (2, 3)].into();
        assert_eq!(fascia_mesh(&p, &tris, &alive).indices.len(), 6);
        alive.remove(&(1, 3));
        assert_eq!(fascia_mesh(&p, &tris, &alive).indices.len(), 3);
    }
}
