//! Input traces. A keyframed TOML trace is written by hand and sampled once per step; every
//! session streams what it sampled to a binary recording of checksummed blocks that replays bit
//! for bit and survives the session being killed.

mod blocks;
mod codec;
mod keys;
mod legacy;
pub mod operator;
mod recording;
mod stream;
#[cfg(test)]
mod tests;

pub use keys::{Key, KeyTrace};
pub use recording::{Recording, Tail, TuningRecord, TuningRecordError};
pub use stream::{RecordingHeader, RecordingSink, RecordingWriter};
