//! Force-feedback devices over their vendors' C libraries: 3D Systems OpenHaptics HD
//! ([`HdDevice`]: Phantom Omni, Touch, Touch X, Premium) and Force Dimension DHD
//! ([`DhdDevice`]: Novint Falcon, omega.x, delta.x, sigma.x).
//!
//! Neither library is linked: each is opened at run time with `libloading`, so Vesalius starts
//! on machines without them and says which one is missing and how to install it. Lookup: when
//! the override variable (`VESALIUS_LIBHD`, `VESALIUS_LIBDHD`) is set, that path and only that
//! path is tried (someone who names a file wants that file, not another copy found elsewhere);
//! otherwise the dynamic loader's search (so `LD_LIBRARY_PATH` works) for `libHD.so`, then
//! `libHD.so.3.4` (`libdhd.so`, then `libdhd.so.3`).
//!
//! A library once opened stays loaded for the life of the process: OpenHaptics must never be
//! unloaded after a device was opened (its scheduler and driver threads live inside it), and
//! the function pointers the devices and the servo trampoline hold stay valid for as long as
//! they exist. Each distinct file is opened once and kept in a process-wide table.
//!
//! Units at this API are SI (metres, m/s, newtons, N/m); the conversions from the vendors'
//! units (HD: millimetres, N/mm) happen here.

mod dhd;
mod hd;

use std::ffi::OsString;
use std::path::Path;
use std::sync::{Mutex, PoisonError};

use libloading::Library;

pub use dhd::{
    DHD_DEVICE_DELTA3, DHD_DEVICE_DELTA6, DHD_DEVICE_FALCON, DHD_DEVICE_OMEGA3, DHD_DEVICE_OMEGA33,
    DHD_DEVICE_OMEGA331, DHD_DEVICE_SIGMA331, DhdDevice, ForceStatus,
};
pub use hd::{
    HD_SCHEDULER_RATE_HZ, HdCommand, HdDevice, HdErrorInfo, HdState, ServoStatus, hd_error_name,
};

/// What went wrong with a force-feedback device or its vendor library.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HapticsError {
    /// The vendor library could not be opened.
    #[error(
        "{library} ({vendor}) was not found: {install} and make sure {library} is on \
         LD_LIBRARY_PATH, or set {env_var} to its path (tried {tried})"
    )]
    LibraryMissing {
        /// The library's usual file name, e.g. `libHD.so`.
        library: &'static str,
        /// Who ships it, e.g. "3D Systems OpenHaptics".
        vendor: &'static str,
        /// How to get it, e.g. "install OpenHaptics for Linux".
        install: &'static str,
        /// The variable that names its path, e.g. `VESALIUS_LIBHD`.
        env_var: &'static str,
        /// Each file tried with the loader's reason.
        tried: String,
    },
    /// The library opened but lacks a function the bindings need.
    #[error(
        "{library} has no function {symbol}: it is not the vendor's library or a version too \
         old for Vesalius ({detail})"
    )]
    MissingSymbol {
        /// The file that was opened.
        library: String,
        /// The missing C function.
        symbol: &'static str,
        /// The loader's message.
        detail: String,
    },
    /// `hdInitDevice` failed.
    #[error(
        "hdInitDevice({device}) failed with {name} (0x{code:04X}, internal {internal}): \
         {message}; is the device plugged in, powered, and configured (Touch_Setup)?"
    )]
    HdInit {
        /// The device name passed, or `HD_DEFAULT_DEVICE`.
        device: String,
        /// The HD error code.
        code: u32,
        /// Its name from hdDefines.h, e.g. `HD_COMM_ERROR`.
        name: &'static str,
        /// The driver's internal error code.
        internal: i32,
        /// `hdGetErrorString(code)`.
        message: String,
    },
    /// Another HD call reported an error.
    #[error("{call} failed with {name} (0x{code:04X}, internal {internal}): {message}")]
    HdCall {
        /// The HD function.
        call: &'static str,
        /// The HD error code.
        code: u32,
        /// Its name from hdDefines.h.
        name: &'static str,
        /// The driver's internal error code.
        internal: i32,
        /// `hdGetErrorString(code)`.
        message: String,
    },
    /// The HD device reported an error while the servo loop ran (a fault, a force or velocity
    /// limit, a communication error).
    #[error(
        "the haptic device reported {name} (0x{code:04X}, internal {internal}) during the \
         session: {message}; stop the servo, check the device, and open it again"
    )]
    DeviceFault {
        /// The HD error code, e.g. 0x0300.
        code: u32,
        /// Its name from hdDefines.h, e.g. `HD_DEVICE_FAULT`.
        name: &'static str,
        /// The driver's internal error code.
        internal: i32,
        /// `hdGetErrorString(code)`.
        message: String,
    },
    /// The servo callback panicked; the force was set to zero and the servo stopped.
    #[error("the servo callback panicked: the force was set to zero and the servo stopped")]
    CallbackPanicked,
    /// The servo already runs on this device.
    #[error("the servo already runs on this device: stop it before starting another")]
    ServoRunning,
    /// A device name with a NUL byte cannot be passed to C.
    #[error("the device name {name:?} contains a NUL byte")]
    InvalidDeviceName {
        /// The name given.
        name: String,
    },
    /// `dhdOpen` found no device.
    #[error(
        "dhdOpen found no Force Dimension device: {message}; is it plugged in and powered, and \
         may this user open it (udev rules)?"
    )]
    DhdOpen {
        /// `dhdErrorGetLastStr()`.
        message: String,
    },
    /// Another DHD call failed.
    #[error("{call} failed: {message}")]
    DhdCall {
        /// The DHD function.
        call: &'static str,
        /// `dhdErrorGetLastStr()`.
        message: String,
    },
    /// A force with a NaN or infinite component; zero force was sent instead.
    #[error("the force {force_n:?} N is not finite: zero force was sent instead")]
    NonFiniteForce {
        /// The force asked for.
        force_n: [f64; 3],
    },
    /// An argument outside what the device accepts.
    #[error("{what} = {value} is out of range: expected {expected}")]
    InvalidArgument {
        /// The argument.
        what: &'static str,
        /// Its value.
        value: String,
        /// The accepted range.
        expected: &'static str,
    },
}

/// How one vendor library is found and described in errors.
pub(crate) struct LibrarySpec {
    /// The usual file name, named in errors.
    pub library: &'static str,
    pub vendor: &'static str,
    pub install: &'static str,
    /// The override variable holding a path.
    pub env_var: &'static str,
    /// File names for the loader's search, in order.
    pub names: &'static [&'static str],
}

/// A vendor library that stays loaded for the life of the process.
#[derive(Clone, Copy)]
pub(crate) struct Loaded {
    pub lib: &'static Library,
    /// The file as it was named to the loader, for errors.
    pub label: &'static str,
}

/// Libraries opened so far, by the name given to the loader; never unloaded.
static LOADED: Mutex<Vec<(OsString, Loaded)>> = Mutex::new(Vec::new());

/// Opens `spec`'s library: `path` if given, else the override variable's path if set, else the
/// loader's search for each of `spec.names`.
pub(crate) fn load_library(
    spec: &LibrarySpec,
    path: Option<&Path>,
) -> Result<Loaded, HapticsError> {
    let candidates: Vec<OsString> = match path {
        Some(p) => vec![p.as_os_str().to_owned()],
        None => match std::env::var_os(spec.env_var).filter(|v| !v.is_empty()) {
            Some(p) => vec![p],
            None => spec.names.iter().map(OsString::from).collect(),
        },
    };
    let mut loaded = LOADED.lock().unwrap_or_else(PoisonError::into_inner);
    let mut tried = Vec::new();
    for candidate in candidates {
        if let Some((_, l)) = loaded.iter().find(|(name, _)| *name == candidate) {
            return Ok(*l);
        }
        // SAFETY: opening runs the library's initialisers; the files tried are the vendor's
        // library (or a fake with the same interface) named by the user or the loader's search,
        // which is the trust any dynamically linked program gives its libraries.
        match unsafe { Library::new(&candidate) } {
            Ok(lib) => {
                let label: &'static str =
                    Box::leak(candidate.to_string_lossy().into_owned().into_boxed_str());
                // Leaked on purpose: see the module documentation.
                let l = Loaded {
                    lib: Box::leak(Box::new(lib)),
                    label,
                };
                loaded.push((candidate, l));
                return Ok(l);
            }
            Err(e) => {
                // dlerror names the file when that file is missing, but names only the
                // dependency when one of its dependencies is (libPhantomIOLib42.so).
                let (file, why) = (candidate.to_string_lossy(), e.to_string());
                tried.push(if why.contains(file.as_ref()) {
                    why
                } else {
                    format!("{file}: {why}")
                });
            }
        }
    }
    let tried = if tried.len() == 1 {
        tried.remove(0)
    } else {
        tried.join("; ")
    };
    Err(HapticsError::LibraryMissing {
        library: spec.library,
        vendor: spec.vendor,
        install: spec.install,
        env_var: spec.env_var,
        tried,
    })
}

/// Looks up `symbol` in `lib`.
///
/// # Safety
/// `T` must be the C function pointer type of `symbol` as the vendor declares it.
pub(crate) unsafe fn symbol<T: Copy>(lib: Loaded, symbol: &'static str) -> Result<T, HapticsError> {
    // SAFETY: the caller vouches for `T`; the library is never unloaded, so the pointer copied
    // out of the `Symbol` stays valid for the life of the process.
    match unsafe { lib.lib.get::<T>(symbol.as_bytes()) } {
        Ok(s) => Ok(*s),
        Err(e) => Err(HapticsError::MissingSymbol {
            library: lib.label.to_owned(),
            symbol,
            detail: e.to_string(),
        }),
    }
}

/// Reads a C string the vendor library returned; `None` for a null pointer.
///
/// # Safety
/// `p` is null or points to a NUL-terminated string valid for the duration of the call.
pub(crate) unsafe fn c_text(p: *const std::ffi::c_char) -> Option<String> {
    if p.is_null() {
        return None;
    }
    // SAFETY: non-null, and NUL-terminated per the caller's contract.
    Some(
        unsafe { std::ffi::CStr::from_ptr(p) }
            .to_string_lossy()
            .into_owned(),
    )
}

/// The directory holding the fake `libHD.so` and `libdhd.so` built from `tests/fake/*.c` by
/// the build script. It exists for tests (this crate's and the vesalius binary's, which run
/// with `LD_LIBRARY_PATH` pointing here); it is not part of the API.
#[doc(hidden)]
pub fn fake_library_dir() -> &'static Path {
    Path::new(env!("VESALIUS_FAKE_HAPTICS_DIR"))
}
