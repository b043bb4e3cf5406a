//! A BVH over a deforming surface whose leaves are small patches of faces rather than single
//! faces: up to four faces that lie next to each other at rest (consecutive in Morton order,
//! and no farther from the patch's first face than twice that face's box) share a leaf. A patch
//! leaf costs a quarter of the tree's memory (parry's tree is ~80 bytes a leaf) and of its
//! refit work; a query visits up to three extra faces per leaf, which callers filter anyway
//! (every query here is followed by an exact distance or ray-triangle test).

use glam::Vec3;
use parry3d::bounding_volume::{Aabb, BoundingVolume};
use parry3d::partitioning::{Bvh, BvhBuildStrategy, BvhLeafUpdateStatus};
use parry3d::query::Ray;
use rayon::prelude::*;

/// The fewest patches whose boxes one parallel task computes.
const PATCHES_PER_TASK: usize = 256;

/// Most faces per leaf.
pub const PATCH_FACES: usize = 4;

pub struct FaceBvh {
    bvh: Bvh,
    /// Faces of patch p: `patch_faces[patch_start[p]..patch_start[p + 1]]`.
    patch_start: Vec<u32>,
    patch_faces: Vec<u32>,
    patch_of: Vec<u32>,
    /// Live faces per patch; a patch leaves the tree when its last face is cut.
    live: Vec<u8>,
    /// Per patch: the stamp of the refresh that last listed it.
    stamp: Vec<u32>,
    stamp_now: u32,
    /// Patches due a refresh.
    dirty: Vec<u32>,
    /// Leaves grown past their margin at the last refit, and this refresh.
    changed: Vec<u32>,
    growing: Vec<u32>,
    /// Scratch: the dirty patches' new boxes.
    boxes: Vec<Aabb>,
    /// A leaf was removed: the next refit walks the whole tree.
    full_refit: bool,
}

/// A 30-bit Morton code of `p` inside the box `lo..hi`.
fn morton(p: Vec3, lo: Vec3, hi: Vec3) -> u32 {
    fn spread(v: u32) -> u32 {
        let mut x = v & 0x3ff;
        x = (x | (x << 16)) & 0x0300_00ff;
        x = (x | (x << 8)) & 0x0300_f00f;
        x = (x | (x << 4)) & 0x030c_30c3;
        x = (x | (x << 2)) & 0x0924_9249;
        x
    }
    let t = (p - lo) / (hi - lo).max(Vec3::splat(1e-9));
    let q = (t.clamp(Vec3::ZERO, Vec3::ONE) * 1023.0).as_uvec3();
    spread(q.x) | (spread(q.y) << 1) | (spread(q.z) << 2)
}

impl FaceBvh {
    /// Groups the faces into patches by the Morton order of `keys` (one point per face, at
    /// rest) and builds the tree from each patch's box; `aabb(f)` is face f's box.
    pub fn new(keys: &[Vec3], aabb: impl Fn(usize) -> Aabb) -> Self {
        let n = keys.len();
        let (lo, hi) = keys.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let mut order: Vec<(u32, u32)> = keys
            .iter()
            .enumerate()
            .map(|(f, p)| (morton(*p, lo, hi), f as u32))
            .collect();
        order.sort_unstable();
        let patch_faces: Vec<u32> = order.into_iter().map(|(_, f)| f).collect();
        // Z-order jumps between distant regions at block boundaries: a patch ends there too.
        let mut patch_start = vec![0u32];
        let mut first = 0usize;
        for k in 1..n {
            let f0 = patch_faces[first] as usize;
            let reach = 2.0 * aabb(f0).half_extents().max_element();
            let far = (keys[patch_faces[k] as usize] - keys[f0]).length() > 2.0 * reach;
            if k - first == PATCH_FACES || far {
                patch_start.push(k as u32);
                first = k;
            }
        }
        if n > 0 {
            patch_start.push(n as u32);
        }
        let patches = patch_start.len() - 1;
        let mut patch_of = vec![0u32; n];
        let mut live = vec![0u8; patches];
        for p in 0..patches {
            for k in patch_start[p]..patch_start[p + 1] {
                patch_of[patch_faces[k as usize] as usize] = p as u32;
                live[p] += 1;
            }
        }
        let mut me = FaceBvh {
            bvh: Bvh::new(),
            patch_start,
            patch_faces,
            patch_of,
            live,
            stamp: vec![0; patches],
            stamp_now: 0,
            dirty: Vec::new(),
            changed: Vec::new(),
            growing: Vec::new(),
            boxes: Vec::new(),
            full_refit: false,
        };
        let leaves: Vec<Aabb> = (0..patches)
            .map(|p| me.patch_aabb(p, |f| Some(aabb(f))))
            .collect();
        me.bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves);
        me
    }

    fn faces_of(&self, p: usize) -> &[u32] {
        &self.patch_faces[self.patch_start[p] as usize..self.patch_start[p + 1] as usize]
    }

    /// Union of the boxes of the patch's faces that have one (live faces).
    fn patch_aabb(&self, p: usize, aabb: impl Fn(usize) -> Option<Aabb>) -> Aabb {
        let mut out = Aabb::new_invalid();
        for &f in self.faces_of(p) {
            if let Some(b) = aabb(f as usize) {
                out.merge(&b);
            }
        }
        out
    }

    /// Face `f` moved: its patch's box is refreshed at the next [`FaceBvh::refresh`].
    pub fn mark(&mut self, f: u32) {
        let p = self.patch_of[f as usize] as usize;
        if self.stamp[p] != self.stamp_now.wrapping_add(1) {
            self.stamp[p] = self.stamp_now.wrapping_add(1);
            self.dirty.push(p as u32);
        }
    }

    /// Refits the boxes of the marked patches (`aabb(f)` is None for a cut face). A leaf is
    /// padded by `margin_m` and its ancestors refitted only when it outgrows that padding:
    /// only the paths from grown leaves to the root, unless a leaf was removed since the last
    /// refresh (then the whole tree, in place).
    pub fn refresh(&mut self, aabb: impl Fn(usize) -> Option<Aabb> + Sync, margin_m: f32) {
        self.stamp_now = self.stamp_now.wrapping_add(1);
        let mut growing = std::mem::take(&mut self.growing);
        growing.clear();
        let dirty = std::mem::take(&mut self.dirty);
        // The patches' boxes in parallel (read-only), then the tree in order.
        let mut boxes = std::mem::take(&mut self.boxes);
        let this = &*self;
        dirty
            .par_iter()
            .with_min_len(PATCHES_PER_TASK)
            .map(|&p| this.patch_aabb(p as usize, &aabb))
            .collect_into_vec(&mut boxes);
        for (&p, &b) in dirty.iter().zip(&boxes) {
            if self.live[p as usize] == 0 {
                continue;
            }
            if let Some(s) = self.bvh.update_partially_if_present(b, p, margin_m)
                && s != BvhLeafUpdateStatus::Unchanged
            {
                growing.push(p);
            }
        }
        self.boxes = boxes;
        self.dirty = dirty;
        self.dirty.clear();
        if self.full_refit {
            self.bvh.refit_without_opt();
            self.full_refit = false;
        } else if !growing.is_empty() || !self.changed.is_empty() {
            self.bvh.refit_partial(&self.changed, &growing);
        }
        std::mem::swap(&mut self.changed, &mut growing);
        self.growing = growing;
    }

    /// Face `f` was cut away; its patch leaves the tree with its last face.
    pub fn remove_face(&mut self, f: u32) {
        let p = self.patch_of[f as usize] as usize;
        if self.live[p] == 0 {
            return;
        }
        self.live[p] -= 1;
        if self.live[p] == 0 {
            self.bvh.remove(p as u32);
            self.full_refit = true;
        }
    }

    /// Faces of every patch whose box meets `q` (a superset of the faces that meet it; cut
    /// faces included: callers check).
    pub fn faces_in<'a>(&'a self, q: &'a Aabb) -> impl Iterator<Item = u32> + 'a {
        self.bvh
            .intersect_aabb(q)
            .flat_map(move |p| self.faces_of(p as usize).iter().copied())
    }

    /// The nearest face hit by `ray` within `max_toi`: `hit(f, best)` tests face f and returns
    /// its time of impact if below `best`.
    pub fn cast_ray(
        &self,
        ray: &Ray,
        max_toi: f32,
        hit: impl Fn(u32, f32) -> Option<f32>,
    ) -> Option<(u32, f32)> {
        let best_face = std::cell::Cell::new(None);
        let (_, toi) = self.bvh.cast_ray(ray, max_toi, |p, best| {
            let mut found = None;
            let mut best = best;
            for &f in self.faces_of(p as usize) {
                if let Some(t) = hit(f, best)
                    && t < best
                {
                    best = t;
                    found = Some((f, t));
                }
            }
            let (f, t) = found?;
            best_face.set(Some((f, t)));
            Some(t)
        })?;
        let (f, t) = best_face.get()?;
        (t == toi).then_some((f, toi))
    }

    pub fn root_aabb(&self) -> Aabb {
        self.bvh.root_aabb()
    }

    /// Heap bytes held.
    pub fn heap_bytes(&self) -> usize {
        self.bvh.heap_memory_size()
            + 4 * (self.patch_faces.capacity()
                + self.patch_start.capacity()
                + self.patch_of.capacity()
                + self.stamp.capacity()
                + self.dirty.capacity()
                + self.changed.capacity()
                + self.growing.capacity())
            + self.boxes.capacity() * std::mem::size_of::<Aabb>()
            + self.live.capacity()
    }

    /// Number of leaves (patches with a live face).
    pub fn leaf_count(&self) -> u32 {
        self.bvh.leaf_count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxes(points: &[Vec3], r: f32) -> impl Fn(usize) -> Aabb + '_ {
        move |f| Aabb::new(points[f] - Vec3::splat(r), points[f] + Vec3::splat(r))
    }

    #[test]
    fn patches_group_near_faces_and_queries_find_every_face() {
        // A 20 x 20 grid of faces 1 cm apart.
        let pts: Vec<Vec3> = (0..400)
            .map(|k| Vec3::new((k % 20) as f32 * 0.01, (k / 20) as f32 * 0.01, 0.0))
            .collect();
        let t = FaceBvh::new(&pts, boxes(&pts, 0.004));
        let leaves = t.leaf_count() as usize;
        assert!((100..=200).contains(&leaves), "{leaves} leaves");
        // Patches stay local: at most two cells from their first face (random groups of four
        // would span most of the 19 cm grid).
        let mut mean = 0.0;
        for p in 0..leaves {
            let (lo, hi) = t
                .faces_of(p)
                .iter()
                .fold((Vec3::splat(9.0), Vec3::splat(-9.0)), |(l, h), &f| {
                    (l.min(pts[f as usize]), h.max(pts[f as usize]))
                });
            let span = (hi - lo).max_element();
            assert!(span < 0.021, "patch {p} spans {span} m");
            mean += span / leaves as f32;
        }
        assert!(mean < 0.012, "patches span {mean} m on average");
        for (f, p) in pts.iter().enumerate() {
            let q = Aabb::new(*p, *p);
            assert!(t.faces_in(&q).any(|g| g as usize == f), "face {f}");
        }
    }

    #[test]
    fn moved_faces_are_found_where_they_went_and_cut_patches_leave() {
        let mut pts: Vec<Vec3> = (0..64)
            .map(|k| Vec3::new((k % 8) as f32 * 0.01, (k / 8) as f32 * 0.01, 0.0))
            .collect();
        let mut t = FaceBvh::new(&pts, boxes(&pts, 0.004));
        let moved = 27;
        pts[moved] += Vec3::new(0.0, 0.0, 0.05);
        let q = Aabb::new(pts[moved], pts[moved]);
        assert!(!t.faces_in(&q).any(|g| g as usize == moved));
        t.mark(moved as u32);
        t.refresh(|f| Some(boxes(&pts, 0.004)(f)), 1e-3);
        assert!(t.faces_in(&q).any(|g| g as usize == moved));
        // Cut the whole patch of face 0: the tree loses a leaf and no longer finds it.
        let patch: Vec<u32> = t.faces_of(t.patch_of[0] as usize).to_vec();
        assert!(!patch.contains(&(moved as u32)));
        for &f in &patch {
            t.remove_face(f);
        }
        let alive = |f: usize| !patch.contains(&(f as u32));
        t.refresh(|f| alive(f).then(|| boxes(&pts, 0.004)(f)), 1e-3);
        assert_eq!(t.leaf_count(), 15);
        let q0 = Aabb::new(pts[0], pts[0]);
        assert!(t.faces_in(&q0).all(|g| !patch.contains(&g)));
        // The whole-tree refit after the removal keeps the moved face where it went.
        assert!(t.faces_in(&q).any(|g| g as usize == moved));
    }
}
