//! Builds the fake force-feedback vendor libraries (`tests/fake/fake_hd.c`,
//! `tests/fake/fake_dhd.c`) as shared objects named like the real ones (`libHD.so`,
//! `libdhd.so`) into `$OUT_DIR/fake-haptics`, and hands that directory to the crate as
//! `VESALIUS_FAKE_HAPTICS_DIR` (read by `haptics::fake_library_dir`).
//!
//! The fakes only serve tests, so a failure to compile them is a warning, not a build error:
//! Vesalius itself still builds, and the haptics tests then report the missing library.

use std::path::{Path, PathBuf};
use std::process::Command;

/// (source, shared object name)
const FAKES: [(&str, &str); 2] = [
    ("tests/fake/fake_hd.c", "libHD.so"),
    ("tests/fake/fake_dhd.c", "libdhd.so"),
];

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    for (source, _) in FAKES {
        println!("cargo:rerun-if-changed={source}");
    }
    println!("cargo:rerun-if-changed=tests/fake/fake_common.h");
    let Some(out_dir) = std::env::var_os("OUT_DIR") else {
        println!("cargo:warning=OUT_DIR is not set; the fake haptics libraries are not built");
        return;
    };
    let dir = PathBuf::from(out_dir).join("fake-haptics");
    println!(
        "cargo:rustc-env=VESALIUS_FAKE_HAPTICS_DIR={}",
        dir.display()
    );
    if let Err(e) = build_fakes(&dir) {
        println!("cargo:warning=the fake haptics libraries for the tests were not built: {e}");
    }
}

fn build_fakes(dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    // cc builds static archives; its compiler (with the target's flags) is what is wanted.
    let compiler = cc::Build::new()
        .cargo_metadata(false)
        .try_get_compiler()
        .map_err(|e| format!("no C compiler: {e}"))?;
    for (source, name) in FAKES {
        let output = dir.join(name);
        let mut cmd = compiler.to_command();
        cmd.args(["-shared", "-fPIC", "-O2", "-Wall", "-Wextra"])
            .arg(format!("-Wl,-soname,{name}"))
            .arg("-o")
            .arg(&output)
            .arg(source)
            .args(["-lpthread", "-lm"]);
        run(cmd, source)?;
    }
    Ok(())
}

fn run(mut cmd: Command, source: &str) -> Result<(), String> {
    let out = cmd
        .output()
        .map_err(|e| format!("cannot run the C compiler for {source}: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "compiling {source} failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        ))
    }
}
