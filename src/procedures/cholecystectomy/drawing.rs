//! What the renderer draws of the cholecystectomy: each organ's skin (the outer faces of the
//! lattice cubes whose eight corners are its particles, so the skin moves with them), the
//! vessels and the strands as thin tubes along their intact segments, the fascia's intact
//! triangles.

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
    skin
}

/// The skin drawn at the particles' present places.
pub fn skin_mesh(p: &Particles, skin: &Skin, name: &str, role: SurfaceRole) -> ModelSnapshot {
    let positions: Vec<Vec3> = skin.particles.iter().map(|&i| p.x[i as usize]).collect();
    let normals = crate::mesh::vertex_normals(&positions, &skin.triangles);
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
