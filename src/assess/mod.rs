//! Assessment shared by every procedure: alarms for the supervising surgeon. Each procedure
//! scores its own task (see its folder under `procedures/`).

pub mod alarms;
