//! The sandbox's field: a training box's inside, its floor a pad the block rests on, seen through a forward-viewing scope.

use crate::sim::SurfaceRole::{Viscus, Wall};
use crate::sim::field::{FieldShape, OperativeField};
use glam::Vec3;

pub fn field() -> OperativeField {
    let v = |x, y, z| Vec3::new(x, y, z);
    let shapes = vec![
        FieldShape::cavity(v(0.0, 0.04, 0.0), v(0.24, 0.2, 0.26)),
        FieldShape::blob(v(0.0, -0.02, 0.0), v(0.3, 0.02, 0.3), Wall),
        FieldShape::tube(
            &[
                v(-0.12, 0.0, -0.09),
                v(0.0, 0.01, -0.11),
                v(0.12, 0.0, -0.09),
            ],
            0.015,
            Viscus,
        ),
    ];
    OperativeField::with_scope(shapes, &super::INFO.view, 70.0, 0.0)
}
