//! The cholecystectomy's field, seen through a 30-degree scope from below the liver: the
//! liver's underside with the gallbladder, the duodenum and the stomach below and to the left,
//! the transverse colon and the omentum's fat beneath, under the diaphragm's peritoneum.

use crate::sim::SurfaceRole::{Fat, Viscus};
use crate::sim::field::{FieldShape, OperativeField};
use glam::Vec3;

pub fn field() -> OperativeField {
    let v = |x, y, z| Vec3::new(x, y, z);
    let shapes = vec![
        FieldShape::cavity(v(0.0, 0.0, 0.03), v(0.22, 0.2, 0.19)),
        // The duodenum, which the common bile duct enters.
        FieldShape::tube(
            &[
                v(-0.14, -0.08, 0.0),
                v(-0.07, -0.095, -0.005),
                v(0.0, -0.09, 0.01),
                v(0.04, -0.07, 0.0),
            ],
            0.016,
            Viscus,
        ),
        // The stomach's antrum to the patient's left.
        FieldShape::blob(v(0.11, -0.035, -0.01), v(0.06, 0.045, 0.05), Viscus),
        // The transverse colon and the omentum's fat.
        FieldShape::tube(
            &[
                v(-0.18, -0.13, 0.03),
                v(-0.05, -0.14, 0.05),
                v(0.08, -0.13, 0.04),
                v(0.18, -0.11, 0.0),
            ],
            0.022,
            Viscus,
        ),
        FieldShape::blob(v(0.0, -0.16, 0.08), v(0.16, 0.04, 0.06), Fat),
    ];
    OperativeField::with_scope(shapes, &super::INFO.view, 70.0, 30.0)
}
