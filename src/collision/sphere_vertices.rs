use super::MeshSurface;
use glam::Vec3;
use parry3d::bounding_volume::Aabb;

/// The live faces whose points lie within `radius_m` of `center`, nearest first (ties by index).
pub fn nearest_within(surface: &MeshSurface, center: Vec3, radius_m: f32) -> Vec<(f32, u32)> {
    let q = Aabb::new(
        center - Vec3::splat(radius_m),
        center + Vec3::splat(radius_m),
    );
    let mut found: Vec<(f32, u32)> = surface
        .bvh
        .faces_in(&q)
        .filter(|&f| surface.alive[f as usize])
        .map(|f| ((surface.points[f as usize] - center).length(), f))
        .filter(|&(d, _)| d <= radius_m)
        .collect();
    found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    found
}
