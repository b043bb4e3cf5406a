//! Reference cases as data: a case names its model, what it compares and its tolerance, and
//! measures a reference against the simulator. Models keep theirs in `verify`; a procedure
//! whose cases need its whole scene names them in its description
//! (`ProcedureInfo::cases`), and `vesalius verify` runs both.

/// A registered case: its identity, its tolerance, and the function that measures it.
pub struct Case {
    pub model: &'static str,
    pub case: &'static str,
    pub description: &'static str,
    pub unit: &'static str,
    /// Relative tolerance; each case says in its description or source why this much.
    pub tolerance: f64,
    pub run: fn() -> Measured,
}

/// What a case's run produces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// The independent reference value.
    pub reference: f64,
    /// The simulator's value.
    pub measured: f64,
    /// Simulated time stepped, s (0 for a static case).
    pub simulated_s: f64,
    /// Smallest magnitude the error is taken relative to, so that a reference of zero still
    /// gives a relative error; 0 where the reference is far from zero.
    pub floor: f64,
}

impl Measured {
    /// A static case (no simulated time) with a reference far from zero.
    pub fn at_rest(reference: f64, measured: f64) -> Measured {
        Measured {
            reference,
            measured,
            simulated_s: 0.0,
            floor: 0.0,
        }
    }

    /// A case that could not be set up (say, a mesh that failed to build): its measured value
    /// is NaN, so it fails rather than passing silently.
    pub fn not_run(reference: f64) -> Measured {
        Measured::at_rest(reference, f64::NAN)
    }
}
