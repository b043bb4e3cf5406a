//! The Heller myotomy's field, seen from above through a 30-degree scope: the esophagus at the
//! hiatus between the diaphragm's crura, the stomach below the junction, the liver's left lobe
//! lifted to one side, the aorta deep behind, under the diaphragm's peritoneum.

use crate::sim::SurfaceRole::{Artery, Fat, Tissue, Viscus};
use crate::sim::field::{FieldShape, OperativeField};
use glam::Vec3;

pub fn field() -> OperativeField {
    let v = |x, y, z| Vec3::new(x, y, z);
    let shapes = vec![
        FieldShape::cavity(v(0.0, 0.0, 0.03), v(0.17, 0.15, 0.2)),
        // The stomach below the junction.
        FieldShape::blob(v(0.02, -0.01, -0.05), v(0.065, 0.05, 0.05), Viscus),
        // The crura at the hiatus, either side and behind.
        FieldShape::tube(
            &[
                v(-0.035, -0.02, 0.09),
                v(-0.03, -0.03, 0.04),
                v(-0.01, -0.035, -0.01),
            ],
            0.011,
            Tissue,
        ),
        FieldShape::tube(
            &[
                v(0.035, -0.02, 0.09),
                v(0.03, -0.03, 0.04),
                v(0.01, -0.035, -0.01),
            ],
            0.011,
            Tissue,
        ),
        // The liver's left lobe, lifted aside; fat of the lesser omentum.
        FieldShape::blob(v(-0.085, 0.01, 0.03), v(0.04, 0.03, 0.08), Tissue),
        FieldShape::blob(v(0.07, -0.015, 0.02), v(0.035, 0.02, 0.05), Fat),
        // The aorta, deep.
        FieldShape::tube(
            &[v(0.005, -0.06, 0.12), v(0.005, -0.065, -0.08)],
            0.012,
            Artery,
        ),
        FieldShape::blob(v(0.0, -0.055, 0.04), v(0.09, 0.02, 0.12), Fat),
    ];
    OperativeField::with_scope(shapes, &super::INFO.view, 70.0, 30.0)
}
