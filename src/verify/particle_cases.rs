//! Cases for the cholecystectomy paper's particle models: shape matching against the
//! continuum (a column hanging under its own weight), the adhesive fascia's break force, a
//! vessel chain's tension, and a grasp carrying a weight.

use super::{Case, Measured};
use crate::models::particles::Particles;
use crate::models::particles::adhesion::{Adhesion, AdhesionParams};
use crate::models::particles::chain::Chains;
use crate::models::particles::contacts::Grasp;
use crate::models::particles::shape::{ShapeMatching, frequency_for, lattice_clusters};
use glam::Vec3;

const SHAPE: &str = "shape matching";
const ADHESION: &str = "adhesive fascia";
const CHAIN: &str = "vessel chain";
const GRASP: &str = "particle grasp";
const DT: f32 = 1e-3;
const G: f32 = 9.81;

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: SHAPE,
            case: "shape_matching_hanging_column",
            description: "a 10 x 20 x 10 column of liver (1060 kg/m^3, 5 kPa) at 3.5 mm in \
                          clusters every 3 steps reaching 2.5, pinned along its top, 3 s under \
                          gravity with 2 sweeps a step: its bottom's drop vs the continuum's \
                          rho g H^2 / (2 E); tolerance 10 % (the modulus factor's calibration)",
            unit: "m",
            tolerance: 0.1,
            run: hanging_column,
        },
        Case {
            model: ADHESION,
            case: "adhesion_break_force",
            description: "a 1 cm strand of 5 segments of 1e4 N/m between a pinned particle and \
                          1 g, weakened past 1.1 times its length: the pull (growing 1 N/s) at \
                          which it tears vs (k / n) 0.1 L = 2 N; tolerance 5 %",
            unit: "N",
            tolerance: 0.05,
            run: break_force,
        },
        Case {
            model: CHAIN,
            case: "chain_hanging_tension",
            description: "a chain of 12 particles of 0.1 g, 3 mm apart, 20 g at its end, \
                          hanging from its pinned top (segments of 500 N/m), 1.5 s damped: the \
                          top segment's tension vs the weight below it; tolerance 1 %",
            unit: "N",
            tolerance: 0.01,
            run: chain_tension,
        },
        Case {
            model: GRASP,
            case: "grasp_carries_weight",
            description: "a grasp (200 N/m) holding a 10 g particle under gravity for 3 s, \
                          damped: the tissue's force on the grasper vs m g; tolerance 2 %",
            unit: "N",
            tolerance: 0.02,
            run: grasp_weight,
        },
    ]
}

/// A column of 10 x `ny` x 10 particles `h` metres apart of a tissue of density `rho`
/// (kg/m^3) and modulus `e` (Pa) (the shipped liver: 3.5 mm, 1060 kg/m^3, 5 kPa) in clusters
/// every 3 lattice steps reaching 2.5, pinned along its top layer: the particles, their
/// clusters and the bottom layer's particles; None if the clusters could not be built.
pub(crate) fn column(
    h: f32,
    rho: f32,
    e: f32,
    ny: usize,
) -> Option<(Particles, ShapeMatching, Vec<usize>)> {
    let mut p = Particles::new();
    for a in 0..10 {
        for b in 0..ny {
            for c in 0..10 {
                let x = Vec3::new(a as f32, -(b as f32), c as f32) * h;
                p.add(x, rho * h * h * h, 0);
            }
        }
    }
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let r = 2.5 * h;
    let specs = lattice_clusters(&p.x, &all, h, 3, r, frequency_for(e, rho, r));
    let s = ShapeMatching::new(&p, specs).ok()?;
    for i in 0..p.len() {
        if p.x[i].y == 0.0 {
            p.pin(i);
        }
    }
    let bottom: Vec<usize> = (0..p.len())
        .filter(|&i| p.x[i].y < -(ny as f32 - 1.5) * h)
        .collect();
    Some((p, s, bottom))
}

/// The mean height of particles `of`, m.
fn mean_y(p: &Particles, of: &[usize]) -> f32 {
    of.iter().map(|&i| p.x[i].y).sum::<f32>() / of.len().max(1) as f32
}

/// The continuum's drop of the column's bottom, `rho g H^2 / (2 E)`, m.
fn continuum_sag(h: f32, rho: f32, e: f32, ny: usize) -> f32 {
    let hh = (ny - 1) as f32 * h;
    rho * G * hh * hh / (2.0 * e)
}

/// The column's point damping while it sags, 1/s.
pub(crate) const COLUMN_DAMPING_PER_S: f32 = 20.0;

/// [`column`] 3 s under gravity with `sweeps` a step, damped, on the CPU or (`gpu`) by the
/// GPU's kernels on the first adapter (250 steps a submission): the mean drop of its bottom
/// layer (m) and the continuum's `rho g H^2 / (2 E)`; None if the clusters could not be built,
/// or there is no adapter or it refused them.
pub(crate) fn column_sag_of(
    h: f32,
    rho: f32,
    e: f32,
    ny: usize,
    sweeps: usize,
    gpu: bool,
) -> Option<(f32, f32)> {
    use crate::models::particles::gpu::{Constraints, ParticlesGpu, Stepping};
    let (mut p, mut s, bottom) = column(h, rho, e, ny)?;
    let y0 = mean_y(&p, &bottom);
    let gravity = Vec3::new(0.0, -G, 0.0);
    if gpu {
        let device = crate::gpu::Gpu::headless(false).ok()?;
        let mut k = ParticlesGpu::new(&device, &p, &s, &Constraints::none()).ok()?;
        let how = Stepping {
            dt_s: DT,
            substeps: 1,
            iterations: sweeps as u32,
            gravity_m_per_s2: gravity,
            damping_per_s: COLUMN_DAMPING_PER_S,
            floor_y_m: None,
        };
        let mut left = COLUMN_STEPS;
        while left > 0 {
            let n = left.min(250);
            k.advance(&mut p, &how, n).ok()?;
            left -= n;
        }
        k.download(&mut p).ok()?;
    } else {
        for _ in 0..COLUMN_STEPS {
            p.predict(DT, gravity);
            s.begin_step();
            for _ in 0..sweeps {
                s.project(&mut p, DT);
            }
            p.finish(DT, COLUMN_DAMPING_PER_S);
        }
    }
    Some((y0 - mean_y(&p, &bottom), continuum_sag(h, rho, e, ny)))
}

/// Steps of the hanging column (3 s).
const COLUMN_STEPS: usize = 3000;

fn hanging_column() -> Measured {
    hanging_column_of(0.0035, 1060.0, 5000.0)
}

/// The cases of the particle solver's GPU path (`vesalius verify --compute gpu`).
pub(super) fn gpu_cases() -> Vec<Case> {
    vec![Case {
        model: "shape matching, gpu",
        case: "shape_matching_hanging_column_gpu",
        description: "shape_matching_hanging_column stepped by the GPU's kernels \
                      (shaders/particles.wgsl, 250 steps a submission): its bottom's drop vs \
                      the continuum's rho g H^2 / (2 E); tolerance 10 %, as on the CPU",
        unit: "m",
        tolerance: 0.1,
        run: hanging_column_gpu,
    }]
}

fn hanging_column_gpu() -> Measured {
    let (h, rho, e) = (0.0035, 1060.0, 5000.0);
    let continuum = continuum_sag(h, rho, e, 20);
    match column_sag_of(h, rho, e, 20, 2, true) {
        Some((sag, continuum)) => Measured {
            simulated_s: COLUMN_STEPS as f64 * f64::from(DT),
            ..Measured::at_rest(f64::from(continuum), f64::from(sag))
        },
        None => Measured::not_run(f64::from(continuum)),
    }
}

/// The hanging column's case (10 x 20 x 10 particles, 2 sweeps a step, 3 s) on a lattice
/// `h` metres apart of a tissue of density `rho` and modulus `e`: its bottom's drop against
/// the continuum's. The drop is the same share of the continuum's at every spacing, the
/// column's lattice steps being the same.
pub fn hanging_column_of(h: f32, rho: f32, e: f32) -> Measured {
    let Some((sag, continuum)) = column_sag_of(h, rho, e, 20, 2, false) else {
        return Measured::not_run(0.0);
    };
    Measured {
        simulated_s: COLUMN_STEPS as f64 * f64::from(DT),
        ..Measured::at_rest(f64::from(continuum), f64::from(sag))
    }
}

/// The break-force case's strand: 5 segments of 1e4 N/m, weakened past 1.1 times its length,
/// tearing past 50 % strain.
pub(super) const BREAK_STRAND: AdhesionParams = AdhesionParams {
    segments: 5,
    strand_mass_kg: 1e-6,
    body: 7,
    stiffness_n_per_m: 1e4,
    weak_stiffness_n_per_m: 1e-3,
    breakable_per_strand: 1,
    break_stretch: 1.1,
    tear_strain: 0.5,
};

fn break_force() -> Measured {
    let (l, k, n) = (0.01f32, 1e4f32, 5u32);
    let params = BREAK_STRAND;
    let mut p = Particles::new();
    let fixed = p.add(Vec3::ZERO, 0.0, 1);
    let free = p.add(Vec3::new(l, 0.0, 0.0), 1e-3, 2);
    let Ok(mut a) = Adhesion::new(&mut p, &[(free, fixed)], params, 7) else {
        return Measured::not_run(2.0);
    };
    let reference = f64::from(k / n as f32 * 0.1 * l);
    let mut t = 0.0f32;
    while t < 4.0 {
        t += DT;
        p.add_force(free as usize, Vec3::new(t, 0.0, 0.0));
        p.predict(DT, Vec3::ZERO);
        a.begin_step();
        for _ in 0..10 {
            a.project(&mut p, DT);
        }
        p.finish(DT, 20.0);
        if !a.update(&p).is_empty() {
            return Measured {
                simulated_s: f64::from(t),
                ..Measured::at_rest(reference, f64::from(t))
            };
        }
    }
    Measured::not_run(reference)
}

/// The chain case's vessel: particles, segment stiffness (N/m), mass (kg), load at its end
/// (kg), spacing (m).
pub(super) const HANGING_CHAIN: (usize, f32, f32, f32, f32) = (12, 500.0, 1e-4, 0.02, 0.003);

/// The chain case's particles hanging straight down from the first (pinned), and their chain.
pub(super) fn hanging_chain() -> (Particles, Chains) {
    let (n, k, m, load, h) = HANGING_CHAIN;
    let mut p = Particles::new();
    let ids: Vec<u32> = (0..n)
        .map(|i| {
            let mass = if i + 1 == n { m + load } else { m };
            p.add(Vec3::new(0.0, -(i as f32) * h, 0.0), mass, 0)
        })
        .collect();
    p.pin(0);
    let mut c = Chains::new();
    c.add(&p, &ids, k, 0.0);
    (p, c)
}

fn chain_tension() -> Measured {
    let (n, _, m, load, _) = HANGING_CHAIN;
    let (mut p, mut c) = hanging_chain();
    let steps = 1500;
    for _ in 0..steps {
        p.predict(DT, Vec3::new(0.0, -G, 0.0));
        c.begin_step();
        for _ in 0..2 {
            c.project(&mut p, DT);
        }
        p.finish(DT, 30.0);
    }
    let below = f64::from(((n - 1) as f32 * m + load) * G);
    Measured {
        simulated_s: steps as f64 * f64::from(DT),
        ..Measured::at_rest(below, f64::from(c.tension_n(0, 0)))
    }
}

fn grasp_weight() -> Measured {
    let mut p = Particles::new();
    p.add(Vec3::ZERO, 0.01, 0);
    let jaw = Vec3::new(0.0, 0.001, 0.0);
    let mut g = Grasp::take(&p, jaw, 0.003, 8, 200.0);
    let steps = 3000;
    for _ in 0..steps {
        p.predict(DT, Vec3::new(0.0, -G, 0.0));
        g.begin_step();
        for _ in 0..2 {
            g.project(&mut p, jaw, DT);
        }
        p.finish(DT, 10.0);
    }
    // The tissue pulls the grasper down by the weight: compare magnitudes along -y.
    Measured {
        simulated_s: steps as f64 * f64::from(DT),
        ..Measured::at_rest(f64::from(0.01 * G), f64::from(-g.reaction_n(DT).y))
    }
}
