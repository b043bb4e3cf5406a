//! The partial nephrectomy's operative field, seen through a 30-degree scope from the front:
//! the kidney lies in its perirenal fat on the psoas, the great vessels its renal vessels run
//! to at the midline, the colon reflected medially, the liver's edge above, all under the
//! peritoneum of the flank.

use crate::sim::SurfaceRole::{Artery, Fat, Tissue, Vein, Viscus};
use crate::sim::field::{FieldShape, OperativeField};
use glam::Vec3;

pub fn field() -> OperativeField {
    let v = |x, y, z| Vec3::new(x, y, z);
    let shapes = vec![
        FieldShape::cavity(v(0.0, 0.0, 0.04), v(0.22, 0.21, 0.2)),
        // Perirenal fat the kidney lies in, and the psoas behind it.
        FieldShape::blob(v(0.005, -0.005, -0.04), v(0.055, 0.09, 0.028), Fat),
        FieldShape::tube(
            &[
                v(-0.055, 0.12, -0.07),
                v(-0.06, 0.0, -0.06),
                v(-0.045, -0.16, -0.05),
            ],
            0.024,
            Tissue,
        ),
        // Aorta and vena cava at the midline, where the renal vessels end.
        FieldShape::tube(
            &[v(-0.105, 0.16, -0.015), v(-0.1, -0.17, -0.012)],
            0.011,
            Artery,
        ),
        FieldShape::tube(
            &[v(-0.085, 0.16, 0.004), v(-0.082, -0.17, 0.008)],
            0.012,
            Vein,
        ),
        // The colon, reflected medially, and small bowel below.
        FieldShape::tube(
            &[
                v(-0.12, 0.14, 0.05),
                v(-0.14, 0.04, 0.06),
                v(-0.13, -0.06, 0.05),
                v(-0.08, -0.13, 0.07),
            ],
            0.022,
            Viscus,
        ),
        FieldShape::tube(
            &[
                v(-0.02, -0.12, 0.04),
                v(0.04, -0.13, 0.06),
                v(0.09, -0.11, 0.03),
                v(0.1, -0.15, -0.02),
            ],
            0.016,
            Viscus,
        ),
        // The liver's edge above the upper pole.
        FieldShape::blob(v(0.03, 0.14, 0.0), v(0.13, 0.05, 0.09), Tissue),
        // Fat of the flank beyond the kidney.
        FieldShape::blob(v(0.11, -0.03, -0.05), v(0.045, 0.1, 0.05), Fat),
    ];
    OperativeField::with_scope(shapes, &super::INFO.view, 70.0, 30.0)
}
