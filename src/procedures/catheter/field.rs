//! The catheterisation's field: the bifurcating vessel drawn see-through in the soft tissue it
//! runs in (a bed of fat and muscle behind it, connective tissue around), seen by a
//! forward-viewing camera.

use crate::sim::SurfaceRole::{Fat, Tissue};
use crate::sim::field::{FieldShape, OperativeField};
use glam::Vec3;

pub fn field() -> OperativeField {
    let v = |x, y, z| Vec3::new(x, y, z);
    let shapes = vec![
        FieldShape::cavity(v(0.03, 0.0, 0.04), v(0.22, 0.16, 0.19)),
        FieldShape::blob(v(0.04, 0.0, -0.035), v(0.16, 0.09, 0.022), Fat),
        FieldShape::tube(
            &[
                v(-0.12, -0.07, -0.05),
                v(0.05, -0.075, -0.045),
                v(0.2, -0.07, -0.05),
            ],
            0.025,
            Tissue,
        ),
        FieldShape::tube(
            &[
                v(-0.12, 0.075, -0.05),
                v(0.05, 0.08, -0.045),
                v(0.2, 0.075, -0.05),
            ],
            0.025,
            Tissue,
        ),
    ];
    OperativeField::with_scope(shapes, &super::INFO.view, 70.0, 0.0)
}
