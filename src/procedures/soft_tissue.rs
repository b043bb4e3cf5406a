//! What every procedure built on the soft body shares: the sliders of a tissue table and its
//! live tuning.

use super::Tunable;
use crate::models::{SoftBody, SoftBodyParams, Tuning};
use crate::params::{Params, TuneError, check_tuning};

/// Slider labels with units, in the order of `Tuning::RANGES`.
const LABELS: [&str; 3] = ["spring (N/m)", "damping (1/s)", "offset (mm)"];

/// The sliders of the tissue table `model` (the scenario table and the model share the name).
pub fn tunables(model: &str, p: &SoftBodyParams) -> Vec<Tunable> {
    Tuning::RANGES
        .iter()
        .zip(LABELS)
        .zip(Tuning::of(p).values())
        .map(|(((key, min, max), label), value)| Tunable {
            model: model.to_string(),
            key,
            label,
            min: *min,
            max: *max,
            // Offsets are millimetres on screen.
            scale: if *key == "offset_m" { 1000.0 } else { 1.0 },
            value,
        })
        .collect()
}

/// Tunes `body` and its scenario table `p` from the next step on: every value checked
/// against the table's sliders first, so all change or none.
pub fn tune(
    model: &str,
    p: &mut SoftBodyParams,
    body: &mut SoftBody,
    values: &[(String, f32)],
) -> Result<(), TuneError> {
    check_tuning::<SoftBodyParams>(model, values)?;
    let mut next = *p;
    for (key, v) in values {
        next.set(key, f64::from(*v));
    }
    let t = Tuning::of(&next);
    body.tune(&t);
    t.apply(p);
    Ok(())
}
