//! What the FFI tests share: the fake vendor libraries the build script compiles from
//! `tests/fake/*.c`, opened again by path for their control symbols, a lock (the fakes keep
//! process-wide state), and bounded waits.
#![allow(dead_code)]

use std::ffi::{CString, c_char, c_int, c_long};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use libloading::Library;
use xr_bindings::haptics::fake_library_dir;

pub static LOCK: Mutex<()> = Mutex::new(());

pub fn lock() -> MutexGuard<'static, ()> {
    LOCK.lock().unwrap_or_else(PoisonError::into_inner)
}

pub fn hd_path() -> PathBuf {
    fake_library_dir().join("libHD.so")
}

pub fn dhd_path() -> PathBuf {
    fake_library_dir().join("libdhd.so")
}

/// Runs `f` with the environment variable `key` set to `value`.
pub fn with_env<T>(key: &str, value: &str, f: impl FnOnce() -> T) -> T {
    // SAFETY: every test in this file holds LOCK, so no other thread of this process reads or
    // writes the environment meanwhile.
    unsafe { std::env::set_var(key, value) };
    let r = f();
    // SAFETY: as above.
    unsafe { std::env::remove_var(key) };
    r
}

/// Waits until `cond` holds; the bound only turns a hang into a failure.
pub fn wait_for(what: &str, mut cond: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(30);
    while !cond() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Asserts that `text` contains each of `parts`.
pub fn assert_mentions(text: &str, parts: &[&str]) {
    for p in parts {
        assert!(text.contains(p), "{text:?} does not mention {p:?}");
    }
}

pub fn approx(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
}

/// One of the fake libraries, opened again by path (the loader hands back the instance the
/// bindings opened, so its state is shared), with its control symbols.
pub struct Fake {
    lib: Library,
    prefix: &'static str,
}

impl Fake {
    pub fn open(path: &Path, prefix: &'static str) -> Fake {
        // SAFETY: the fake's initialiser only reads environment variables.
        let lib = unsafe { Library::new(path) }
            .unwrap_or_else(|e| panic!("{}: {e} (the build script builds it)", path.display()));
        Fake { lib, prefix }
    }

    /// # Safety
    /// `T` must be the prototype of `<prefix>_<name>` in tests/fake/*.c.
    pub unsafe fn sym<T: Copy>(&self, name: &str) -> T {
        let full = format!("{}_{name}", self.prefix);
        // SAFETY: per the caller; the library stays loaded while `self` lives.
        unsafe {
            *self
                .lib
                .get::<T>(full.as_bytes())
                .unwrap_or_else(|e| panic!("{full}: {e}"))
        }
    }

    pub fn reset(&self) {
        // SAFETY: `void fake_*_reset(void)`.
        unsafe { self.sym::<unsafe extern "C" fn()>("reset")() }
    }

    pub fn set_int(&self, name: &str, v: c_int) {
        // SAFETY: every `set_*` named with this helper is `void f(int)`.
        unsafe { self.sym::<unsafe extern "C" fn(c_int)>(name)(v) }
    }

    pub fn set_xyz(&self, name: &str, v: [f64; 3]) {
        // SAFETY: every `set_*` named with this helper is `void f(double, double, double)`.
        unsafe { self.sym::<unsafe extern "C" fn(f64, f64, f64)>(name)(v[0], v[1], v[2]) }
    }

    pub fn get_int(&self, name: &str) -> c_int {
        // SAFETY: every query named with this helper is `int f(void)`.
        unsafe { self.sym::<unsafe extern "C" fn() -> c_int>(name)() }
    }

    pub fn get_long(&self, name: &str) -> c_long {
        // SAFETY: every query named with this helper is `long f(void)`.
        unsafe { self.sym::<unsafe extern "C" fn() -> c_long>(name)() }
    }

    pub fn get_f64(&self, name: &str) -> f64 {
        // SAFETY: every query named with this helper is `double f(void)`.
        unsafe { self.sym::<unsafe extern "C" fn() -> f64>(name)() }
    }

    /// How often the vendor call `call` was made since the last reset.
    pub fn calls(&self, call: &str) -> c_long {
        let c = CString::new(call).expect("a call name");
        // SAFETY: `long fake_*_call_count(const char*)`, reading the string during the call.
        let n = unsafe {
            self.sym::<unsafe extern "C" fn(*const c_char) -> c_long>("call_count")(c.as_ptr())
        };
        assert!(n >= 0, "the fake does not export {call}");
        n
    }

    /// The forces the fake received, one per frame (HD) or per call (DHD).
    pub fn force_log(&self) -> Vec<[f64; 3]> {
        // SAFETY: `long fake_*_force_log(double* out, int max)`, which writes at most `max`
        // triples; with a null `out` it only returns the count.
        unsafe {
            let f = self.sym::<unsafe extern "C" fn(*mut f64, c_int) -> c_long>("force_log");
            let n = f(std::ptr::null_mut(), 0);
            let mut out = vec![[0.0f64; 3]; usize::try_from(n).expect("a count")];
            let max = c_int::try_from(out.len()).expect("a small log");
            f(out.as_mut_ptr().cast(), max);
            out
        }
    }

    pub fn last_force(&self) -> [f64; 3] {
        let mut f = [0.0f64; 3];
        // SAFETY: `void fake_*_last_force(double* out)`, which writes 3 doubles.
        unsafe { self.sym::<unsafe extern "C" fn(*mut f64)>("last_force")(f.as_mut_ptr()) };
        f
    }
}

pub fn fake_hd() -> Fake {
    Fake::open(&hd_path(), "fake_hd")
}

pub fn fake_dhd() -> Fake {
    Fake::open(&dhd_path(), "fake_dhd")
}
