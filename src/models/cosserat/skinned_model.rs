//! The rectum rod as a tissue model: the world's contacts, the step, the collider, the
//! skinned surface, checkpoints and the digest.

use super::SkinnedRod;
use crate::collision::GeneralizedCylinder;
use crate::mesh::TriMesh;
use crate::models::cosserat::skin::{RodPose, Selection, Skin};
use crate::sim::Fnv;
use crate::sim::{
    Collider, Contact, ContactKind, EventKind, ModelOutput, ModelSizes, ModelSnapshot, SurfaceRole,
    TissueModel, ToolId,
};
use glam::{DVec3, Vec3};

impl SkinnedRod {
    /// The world's contacts: a `Sphere` (an instrument tip) presses the bounding spheres as
    /// [`SkinnedRod::press_sphere`]; a `Grasp` takes hold within the contact's radius of the
    /// surface (if its hand holds nothing) and pulls to the contact's point while it keeps
    /// coming, and lets go on the first step without one (with `Grasp` and `Release` events).
    /// A grasp taken through [`SkinnedRod::grasp`] stays the caller's: a `Grasp` contact for its
    /// hand moves its jaw but never lets it go. `Press` (a pressure over a surface patch, the
    /// soft body's contact) is ignored: the rod meets tools through its spheres.
    fn take_contacts(&mut self, contacts: &[Contact], out: &mut ModelOutput) {
        let mut grasping = [false; 2];
        for c in contacts {
            let hand = c.tool.index();
            match c.kind {
                // The rod meets a capsule at its working end only (its own instruments
                // press it through their shapes' spheres).
                ContactKind::Sphere { radius_m } | ContactKind::Capsule { radius_m, .. } => {
                    self.press_sphere(c.point, radius_m, hand);
                }
                ContactKind::Grasp { radius_m, .. } => {
                    grasping[hand] = true;
                    if self.grips[hand].is_none() {
                        let reach = f64::from(radius_m).max(0.0);
                        if !self.grasp_within(hand, c.point, reach) {
                            continue;
                        }
                        self.world_grip[hand] = true;
                        out.events.push(EventKind::Grasp {
                            tool: c.tool.name().to_string(),
                            model: self.name.clone(),
                            vertices: 1,
                        });
                    }
                    self.hold(hand, c.point);
                }
                ContactKind::Press { .. } => {}
            }
        }
        for (hand, tool) in ToolId::BOTH.into_iter().enumerate() {
            if self.world_grip[hand] && !grasping[hand] {
                self.release(hand);
                out.events.push(EventKind::Release {
                    tool: tool.name().to_string(),
                });
            }
        }
    }

    /// The surface mesh where the rod carries it, with area-weighted vertex normals.
    pub fn surface_now(&self) -> (Vec<Vec3>, Vec<Vec3>) {
        carried_surface(&self.skin, &self.surface, RodPose::of(&self.rod))
    }

    /// The surface as the rod carries it now, for the renderer.
    pub fn mesh(&self) -> ModelSnapshot {
        let (positions, normals) = self.surface_now();
        mesh_of(&self.name, &self.surface, positions, normals)
    }

    /// [`SkinnedRod::mesh`] of the rod as it is now, built later on any thread: the pose is
    /// copied now (a few hundred bytes), the surface and its skin shared.
    pub fn mesh_later(&self) -> impl FnOnce() -> ModelSnapshot + Send + 'static {
        let (skin, surface, name) = (self.skin.clone(), self.surface.clone(), self.name.clone());
        let (positions, frames) = (self.rod.positions().to_vec(), self.rod.frames().to_vec());
        move || {
            let pose = RodPose {
                positions: &positions,
                frames: &frames,
            };
            let (p, n) = carried_surface(&skin, &surface, pose);
            mesh_of(&name, &surface, p, n)
        }
    }
}

/// `surface` where `skin` carries it on `pose`, with area-weighted vertex normals.
fn carried_surface(skin: &Skin, surface: &TriMesh, pose: RodPose<'_>) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut positions = vec![Vec3::ZERO; skin.len()];
    // The skin was bound to this rod's nodes and the buffer sized to it: this cannot fail.
    if skin
        .place_pose(pose, Selection::All, &mut positions)
        .is_err()
    {
        positions.clone_from(&surface.positions);
    }
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in &surface.triangles {
        let [a, b, c] = t.map(|v| v as usize);
        if let (Some(&pa), Some(&pb), Some(&pc)) =
            (positions.get(a), positions.get(b), positions.get(c))
        {
            let n = (pb - pa).cross(pc - pa);
            normals[a] += n;
            normals[b] += n;
            normals[c] += n;
        }
    }
    for n in &mut normals {
        *n = n.normalize_or(Vec3::Y);
    }
    (positions, normals)
}

/// The renderer's mesh `name` of `surface` at `positions` with `normals`.
fn mesh_of(
    name: &str,
    surface: &TriMesh,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
) -> ModelSnapshot {
    let cut_edge = vec![false; positions.len()];
    ModelSnapshot {
        seared: Vec::new(),
        name: name.to_string(),
        positions,
        normals,
        indices: surface.triangles.iter().flatten().copied().collect(),
        regions: vec![0; surface.triangles.len()],
        roles: vec![SurfaceRole::Tissue],
        cut_edge,
    }
}

impl TissueModel for SkinnedRod {
    fn name(&self) -> &str {
        &self.name
    }

    fn kind(&self) -> &'static str {
        "cosserat_rod"
    }

    /// Vertices: the rod's nodes; triangles: the surface mesh's; constraints: the elements'
    /// shear-stretch, the joints' bend-twist and the two clamps.
    fn sizes(&self) -> ModelSizes {
        let n = self.rod.elements();
        ModelSizes {
            vertices: n + 1,
            triangles: self.surface.triangles.len(),
            constraints: n + n.saturating_sub(1) + 2,
        }
    }

    fn step(&mut self, dt_s: f32, contacts: &[Contact], out: &mut ModelOutput) {
        self.take_contacts(contacts, out);
        let reactions = self.advance(f64::from(dt_s));
        for (tool, r) in ToolId::BOTH.into_iter().zip(reactions) {
            if let Some(r) = r {
                out.reactions.push((tool, r));
            }
        }
    }

    fn collider(&self) -> Collider<'_> {
        Collider::Tube(
            GeneralizedCylinder {
                centreline: &self.centre,
                radii: &self.radii,
            },
            &[],
        )
    }

    fn render_mesh(&mut self) -> ModelSnapshot {
        self.mesh()
    }

    fn checkpoint(&mut self) {
        self.saved.clone_from(&self.rod);
        self.saved_grips = self.grips;
        self.saved_world_grip = self.world_grip;
    }

    fn restore(&mut self) {
        self.rod.clone_from(&self.saved);
        self.grips = self.saved_grips;
        self.world_grip = self.saved_world_grip;
        self.load.iter_mut().for_each(|f| *f = DVec3::ZERO);
        self.pending = [Vec3::ZERO; 2];
        self.touched = [false; 2];
        self.refresh_centres();
    }

    fn state_is_finite(&self) -> bool {
        self.rod.is_finite()
    }

    /// A NaN speed on the rod's middle node (the given loads refuse a NaN force).
    fn inject_nan(&mut self) -> bool {
        self.rod.inject_nan()
    }

    /// The rod's digest, then each grasp's material point and jaw.
    fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        let rod = self.rod.state_hash();
        h.write(rod as u32);
        h.write((rod >> 32) as u32);
        for g in &self.grips {
            let Some(g) = g else {
                h.write(u32::MAX);
                continue;
            };
            h.write(g.element as u32);
            let words = [g.t]
                .into_iter()
                .chain(g.offset.to_array())
                .chain(g.jaw.to_array());
            for w in words {
                let b = w.to_bits();
                h.write(b as u32);
                h.write((b >> 32) as u32);
            }
        }
        h.0
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        let s = &self.surface;
        vec![
            ("skin", self.skin.heap_bytes()),
            ("surface", b(&s.positions) + b(&s.triangles)),
            (
                "nodes",
                b(&self.rest) + b(&self.share) + b(&self.centre) + b(&self.radii) + b(&self.load),
            ),
        ]
    }

    fn point(&self, i: u32) -> Option<Vec3> {
        self.centre.get(i as usize).copied()
    }

    fn apply_point_forces(&mut self, forces: &[(u32, Vec3)]) {
        for &(i, f) in forces {
            self.add_node_force(i as usize, f.as_dvec3());
        }
    }
}
