//! The abdominal esophagus and lower esophageal sphincter of the myotomy paper as a
//! boundary-element solid: a thick-walled tube 60 mm long, held at both ends (the diaphragm
//! above, the fundus below), under 30 mmHg inside, E = 5.222 kPa.
//!
//! The model's frame: the tube's axis is `z`, from the diaphragm (`z = 0`) to the fundus
//! (`z = length`); the anterior wall, where the surgeon works, faces `+y`.
//!
//! Choices the paper leaves open, documented here:
//! - the radii: the paper's mesh is segmented from the Visible Human; ours is a generated
//!   tube of 10 mm outer radius with a 4 mm wall (a distended abdominal esophagus is about
//!   20 mm across, its muscular wall 3-5 mm thick);
//! - the resolution: 30 divisions around and 30 along with the wall's ends as single annuli
//!   make 3,720 triangles on 1,860 vertices, `N = 11,160` unknowns, against the paper's 3,726
//!   triangles and `N = 11,178`;
//! - Poisson's ratio 0.49: soft tissue is nearly incompressible, and Kelvin's solutions are
//!   singular at exactly 0.5 ([`crate::models::bem::kelvin`]).

use crate::models::bem::{Condition, Face, Material, Problem, Sector, Surface};
use glam::DVec3;

/// 1 mmHg in pascals.
pub const PA_PER_MMHG: f64 = 133.322_387_415;

/// The esophagus's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EsophagusParams {
    pub length_m: f64,
    pub outer_radius_m: f64,
    pub wall_m: f64,
    pub around: usize,
    pub along: usize,
    pub young_pa: f64,
    pub poisson: f64,
    pub pressure_mmhg: f64,
    /// The anterior arc where instruments may press (the precomputed field), degrees.
    pub field_arc_deg: f64,
}

impl Default for EsophagusParams {
    fn default() -> Self {
        EsophagusParams {
            length_m: 0.060,
            outer_radius_m: 0.010,
            wall_m: 0.004,
            around: 30,
            along: 30,
            young_pa: 5222.0,
            poisson: 0.49,
            pressure_mmhg: 30.0,
            field_arc_deg: 90.0,
        }
    }
}

/// The esophagus: its surface, its boundary-value problem, and the field elements (outer
/// wall, within the anterior arc).
#[derive(Debug, Clone)]
pub struct Esophagus {
    pub surface: Surface,
    pub problem: Problem,
    pub field: Vec<usize>,
}

impl Esophagus {
    pub fn new(p: &EsophagusParams) -> Esophagus {
        let sector = Sector {
            inner_m: p.outer_radius_m - p.wall_m,
            outer_m: p.outer_radius_m,
            length_m: p.length_m,
            span_rad: std::f64::consts::TAU,
            around: p.around,
            through: 1,
            along: p.along,
        };
        let surface = sector.surface();
        let elements = surface.elements();
        let pressure = p.pressure_mmhg * PA_PER_MMHG;
        let conditions = surface
            .faces
            .iter()
            .zip(&elements)
            .map(|(f, e)| match f {
                Face::End(_) => Condition::fixed(),
                // The lumen's pressure pushes on the wall: traction `-P n`.
                Face::Inner => Condition::traction(-e.normal * pressure),
                _ => Condition::traction(DVec3::ZERO),
            })
            .collect();
        let half_arc = (0.5 * p.field_arc_deg).to_radians();
        let field = surface
            .faces
            .iter()
            .zip(&elements)
            .enumerate()
            .filter(|(_, (f, e))| {
                let radial = DVec3::new(e.centroid.x, e.centroid.y, 0.0).normalize_or_zero();
                **f == Face::Outer && radial.dot(DVec3::Y) >= half_arc.cos()
            })
            .map(|(k, _)| k)
            .collect();
        Esophagus {
            surface,
            problem: Problem {
                elements,
                material: Material {
                    young_pa: p.young_pa,
                    poisson: p.poisson,
                },
                conditions,
            },
            field,
        }
    }
}
