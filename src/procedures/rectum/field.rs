//! The rectum dissection's field: the pelvis seen through a 30-degree scope, the rectum in its
//! mesorectal fat and fascia lying on the presacral fat, the bladder in front, loops of small
//! bowel and the sigmoid colon above, the iliac vessels at the sides, under the pelvic
//! peritoneum.

use crate::sim::SurfaceRole::{Artery, Fat, Tissue, Vein, Viscus};
use crate::sim::field::{FieldShape, OperativeField};
use glam::Vec3;

pub fn field() -> OperativeField {
    let v = |x, y, z| Vec3::new(x, y, z);
    let shapes = vec![
        FieldShape::cavity(v(0.07, 0.0, 0.0), v(0.21, 0.2, 0.17)),
        // Presacral fat and the sacrum's curve behind the mesorectum.
        FieldShape::blob(v(0.07, -0.12, 0.0), v(0.16, 0.035, 0.09), Fat),
        // The bladder.
        FieldShape::blob(v(-0.035, 0.01, 0.0), v(0.035, 0.045, 0.06), Viscus),
        // The sigmoid colon rising out of the pelvis, and small bowel loops.
        FieldShape::tube(
            &[
                v(0.14, 0.0, 0.0),
                v(0.18, 0.03, -0.03),
                v(0.2, 0.06, -0.08),
                v(0.16, 0.09, -0.12),
            ],
            0.02,
            Viscus,
        ),
        FieldShape::tube(
            &[
                v(0.0, 0.1, -0.1),
                v(0.06, 0.12, -0.08),
                v(0.12, 0.1, -0.11),
                v(0.18, 0.12, -0.06),
            ],
            0.016,
            Viscus,
        ),
        // Iliac vessels and the pelvic side walls' muscle.
        FieldShape::tube(
            &[
                v(0.2, -0.03, 0.1),
                v(0.08, -0.05, 0.11),
                v(-0.04, -0.04, 0.1),
            ],
            0.007,
            Artery,
        ),
        FieldShape::tube(
            &[
                v(0.2, -0.04, 0.115),
                v(0.08, -0.065, 0.12),
                v(-0.04, -0.055, 0.115),
            ],
            0.009,
            Vein,
        ),
        FieldShape::tube(
            &[
                v(0.2, -0.03, -0.1),
                v(0.08, -0.05, -0.11),
                v(-0.04, -0.04, -0.1),
            ],
            0.007,
            Artery,
        ),
        FieldShape::blob(v(0.05, -0.04, 0.15), v(0.12, 0.06, 0.025), Tissue),
        FieldShape::blob(v(0.05, -0.04, -0.15), v(0.12, 0.06, 0.025), Tissue),
    ];
    OperativeField::with_scope(shapes, &super::INFO.view, 70.0, 30.0)
}
