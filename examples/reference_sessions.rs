//! Writes the shipped reference sessions (`assets/sessions/<procedure>/expert-N.toml` and
//! `novice-N.toml`, five of each): `cargo run --release --example reference_sessions`.
//!
//! Each is the procedure's task plan (the keys of its demo trace: where each instrument must
//! be and what it must press there) performed by the operator model of
//! `vesalius::trace::operator` as an experienced surgeon or as a first-week trainee, drawn
//! with its own seed. The traces play in the simulated headset (`vesalius run P --xr-sim
//! TRACE`) and headless (`vesalius run P --headless --trace TRACE`). No person operated them;
//! README "Reference sessions" says how a centre replaces them with its own surgeons'.

use std::path::Path;
use vesalius::trace::KeyTrace;
use vesalius::trace::operator::{EXPERT, NOVICE, perform};

/// How many sessions of each persona.
const EACH: u64 = 5;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let only: Vec<String> = std::env::args().skip(1).collect();
    for info in vesalius::registry::CATALOG.iter() {
        if !only.is_empty() && !only.iter().any(|o| o == info.name) {
            continue;
        }
        let plan_file = format!("assets/traces/{}-demo.toml", info.name);
        let plan = KeyTrace::load(Path::new(&plan_file))?;
        let dir = format!("assets/sessions/{}", info.name);
        std::fs::create_dir_all(&dir)?;
        for who in [&EXPERT, &NOVICE] {
            for n in 1..=EACH {
                let seed = vesalius::assess::tree::fnv1a(
                    format!("{}/{}/{n}", info.name, who.name).as_bytes(),
                );
                let p = perform(&plan, who, seed);
                let header = format!(
                    "Reference session: the {} plan ({plan_file}) performed by the operator\n\
                     model (src/trace/operator.rs) as a{} {}, seed {seed:#018x}, pace {:.2} x\n\
                     the plan's; {:.1} s. Written by examples/reference_sessions.rs.",
                    info.name,
                    if who.name.starts_with('e') { "n" } else { "" },
                    who.name,
                    p.pace,
                    p.duration_s()
                );
                let file = format!("{dir}/{}-{n}.toml", who.name);
                std::fs::write(&file, p.toml(&header))?;
                println!("{file}: {:.1} s", p.duration_s());
            }
        }
    }
    Ok(())
}
