//! Force Dimension DHD SDK (`libdhd.so`): Novint Falcon, omega.x, delta.x, sigma.x.
//!
//! DHD has no scheduler of its own: the caller runs the servo loop (Vesalius' main crate runs a
//! 1 kHz thread) and calls [`DhdDevice::set_force_n`] and [`DhdDevice::position_m`] from it.
//! DHD works in metres and newtons, so values pass through unchanged. Every call names the
//! device ID `dhdOpen` returned: the SDK's C++ default argument (-1, "the current device") does
//! not exist over FFI.

use std::cell::Cell;
use std::ffi::{c_char, c_int, c_uchar, c_uint};
use std::marker::PhantomData;
use std::path::Path;
use std::time::Duration;

use super::{HapticsError, LibrarySpec, Loaded, c_text, load_library, symbol};

/// Novint Falcon (`dhdGetSystemType`).
pub const DHD_DEVICE_FALCON: i32 = 60;
/// omega.3.
pub const DHD_DEVICE_OMEGA3: i32 = 33;
/// omega.6.
pub const DHD_DEVICE_OMEGA33: i32 = 34;
/// omega.7.
pub const DHD_DEVICE_OMEGA331: i32 = 35;
/// delta.3.
pub const DHD_DEVICE_DELTA3: i32 = 63;
/// delta.6.
pub const DHD_DEVICE_DELTA6: i32 = 64;
/// sigma.7.
pub const DHD_DEVICE_SIGMA331: i32 = 104;

const DHD_TIMEGUARD: c_int = 1;
const DHD_MOTOR_SATURATED: c_int = 2;

/// The watchdog's unit: 125 us.
const WATCHDOG_UNIT_NS: u128 = 125_000;

static DHD_SPEC: LibrarySpec = LibrarySpec {
    library: "libdhd.so",
    vendor: "Force Dimension SDK",
    install: "install the Force Dimension SDK",
    env_var: "VESALIUS_LIBDHD",
    names: &["libdhd.so", "libdhd.so.3"],
};

/// The DHD functions Vesalius calls, as C function pointers into the loaded library.
#[derive(Clone, Copy)]
struct DhdApi {
    open: unsafe extern "C" fn() -> c_int,
    close: unsafe extern "C" fn(c_char) -> c_int,
    get_system_type: unsafe extern "C" fn(c_char) -> c_int,
    get_system_name: unsafe extern "C" fn(c_char) -> *const c_char,
    enable_force: unsafe extern "C" fn(c_uchar, c_char) -> c_int,
    get_position: unsafe extern "C" fn(*mut f64, *mut f64, *mut f64, c_char) -> c_int,
    set_force: unsafe extern "C" fn(f64, f64, f64, c_char) -> c_int,
    /// `unsigned int` in the vendor's dhdc.h.
    get_button_mask: unsafe extern "C" fn(c_char) -> c_uint,
    set_watchdog: unsafe extern "C" fn(c_uchar, c_char) -> c_int,
    /// Newer SDKs only: optional so older ones still open.
    get_max_force: Option<unsafe extern "C" fn(c_char) -> f64>,
    set_max_force: Option<unsafe extern "C" fn(f64, c_char) -> c_int>,
    error_get_last_str: unsafe extern "C" fn() -> *const c_char,
}

impl DhdApi {
    fn load(lib: Loaded) -> Result<Self, HapticsError> {
        // SAFETY: each type is the C prototype of the function of that name in Force
        // Dimension's dhdc.h (as listed in shared/HAPTICS.md), with `char ID` as c_char.
        unsafe {
            Ok(Self {
                open: symbol(lib, "dhdOpen")?,
                close: symbol(lib, "dhdClose")?,
                get_system_type: symbol(lib, "dhdGetSystemType")?,
                get_system_name: symbol(lib, "dhdGetSystemName")?,
                enable_force: symbol(lib, "dhdEnableForce")?,
                get_position: symbol(lib, "dhdGetPosition")?,
                set_force: symbol(lib, "dhdSetForce")?,
                get_button_mask: symbol(lib, "dhdGetButtonMask")?,
                set_watchdog: symbol(lib, "dhdSetWatchdog")?,
                get_max_force: symbol(lib, "dhdGetMaxForce").ok(),
                set_max_force: symbol(lib, "dhdSetMaxForce").ok(),
                error_get_last_str: symbol(lib, "dhdErrorGetLastStr")?,
            })
        }
    }

    fn last_error(&self) -> String {
        // SAFETY: dhdErrorGetLastStr returns a string the SDK owns (or null), read at once.
        unsafe { c_text((self.error_get_last_str)()) }
            .unwrap_or_else(|| "(no description)".to_owned())
    }

    fn call_error(&self, call: &'static str) -> HapticsError {
        HapticsError::DhdCall {
            call,
            message: self.last_error(),
        }
    }
}

/// What `dhdSetForce` said besides success.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ForceStatus {
    /// `DHD_MOTOR_SATURATED`: a motor hit its limit and the force was clipped.
    pub saturated: bool,
    /// `DHD_TIMEGUARD`: called faster than the device refreshes; not an error.
    pub timeguard: bool,
}

/// An open Force Dimension device. Dropping it closes it.
///
/// `Send`, so the servo thread may own it, but not `Sync`: DHD calls for one device are made
/// from one thread at a time.
pub struct DhdDevice {
    api: DhdApi,
    id: c_char,
    open: bool,
    _not_sync: PhantomData<Cell<()>>,
}

impl DhdDevice {
    /// Loads libdhd (see the module documentation for the lookup) and opens the first
    /// available device (`dhdOpen`).
    pub fn open() -> Result<Self, HapticsError> {
        Self::open_with(load_library(&DHD_SPEC, None)?)
    }

    /// Like [`DhdDevice::open`] with the library at `library` (no search).
    pub fn open_from(library: &Path) -> Result<Self, HapticsError> {
        Self::open_with(load_library(&DHD_SPEC, Some(library))?)
    }

    fn open_with(lib: Loaded) -> Result<Self, HapticsError> {
        let api = DhdApi::load(lib)?;
        // SAFETY: a plain DHD call.
        let id = unsafe { (api.open)() };
        if id < 0 {
            return Err(HapticsError::DhdOpen {
                message: api.last_error(),
            });
        }
        let id = c_char::try_from(id).map_err(|_| HapticsError::DhdOpen {
            message: format!("it returned the device ID {id}, beyond a C char"),
        })?;
        Ok(Self {
            api,
            id,
            open: true,
            _not_sync: PhantomData,
        })
    }

    /// The device ID `dhdOpen` returned.
    pub fn id(&self) -> i32 {
        i32::from(self.id)
    }

    /// The device's name, e.g. "Falcon" or "omega.3" (`dhdGetSystemName`).
    pub fn system_name(&self) -> Result<String, HapticsError> {
        // SAFETY: the ID dhdOpen returned; the string is the SDK's, read at once.
        unsafe { c_text((self.api.get_system_name)(self.id)) }
            .ok_or_else(|| self.api.call_error("dhdGetSystemName"))
    }

    /// The device type, e.g. [`DHD_DEVICE_FALCON`] (`dhdGetSystemType`).
    pub fn system_type(&self) -> Result<i32, HapticsError> {
        // SAFETY: the ID dhdOpen returned.
        let t = unsafe { (self.api.get_system_type)(self.id) };
        if t < 0 {
            Err(self.api.call_error("dhdGetSystemType"))
        } else {
            Ok(t)
        }
    }

    /// The force limit the SDK applies, newtons; `None` for no limit (`dhdGetMaxForce`
    /// reports a negative value). `Err(MissingSymbol)` with an SDK too old to have it.
    pub fn max_force_n(&self) -> Result<Option<f64>, HapticsError> {
        let get = self
            .api
            .get_max_force
            .ok_or_else(|| missing("dhdGetMaxForce"))?;
        // SAFETY: the ID dhdOpen returned.
        let f = unsafe { get(self.id) };
        Ok((f >= 0.0).then_some(f))
    }

    /// Sets the force limit the SDK applies, newtons; `None` removes it (`dhdSetMaxForce`).
    pub fn set_max_force_n(&mut self, max_n: Option<f64>) -> Result<(), HapticsError> {
        let set = self
            .api
            .set_max_force
            .ok_or_else(|| missing("dhdSetMaxForce"))?;
        let value = match max_n {
            None => -1.0,
            Some(f) if f.is_finite() && f >= 0.0 => f,
            Some(f) => {
                return Err(HapticsError::InvalidArgument {
                    what: "max force (N)",
                    value: f.to_string(),
                    expected: "a finite force >= 0, or None for no limit",
                });
            }
        };
        // SAFETY: the ID dhdOpen returned.
        if unsafe { set(value, self.id) } < 0 {
            return Err(self.api.call_error("dhdSetMaxForce"));
        }
        Ok(())
    }

    /// Turns force output on or off (`dhdEnableForce`).
    pub fn enable_force(&mut self, on: bool) -> Result<(), HapticsError> {
        // SAFETY: the ID dhdOpen returned.
        if unsafe { (self.api.enable_force)(c_uchar::from(on), self.id) } < 0 {
            return Err(self.api.call_error("dhdEnableForce"));
        }
        Ok(())
    }

    /// Arms the device's watchdog: forces are cut when no force command arrives within
    /// `timeout` (rounded up to the device's unit of 125 us, at most 255 units = 31.875 ms;
    /// zero disables it). Returns the value sent, in units of 125 us. Older SDKs keep this
    /// call in the expert API; their error then says so.
    pub fn set_watchdog(&mut self, timeout: Duration) -> Result<u8, HapticsError> {
        let units = watchdog_units(timeout).ok_or_else(|| HapticsError::InvalidArgument {
            what: "watchdog timeout",
            value: format!("{timeout:?}"),
            expected: "at most 31.875 ms (255 units of 125 us)",
        })?;
        // SAFETY: the ID dhdOpen returned.
        if unsafe { (self.api.set_watchdog)(units, self.id) } < 0 {
            return Err(self.api.call_error("dhdSetWatchdog"));
        }
        Ok(units)
    }

    /// The end effector's position in the device frame, metres (`dhdGetPosition`).
    pub fn position_m(&self) -> Result<[f64; 3], HapticsError> {
        let mut p = [0.0f64; 3];
        let [x, y, z] = &mut p;
        // SAFETY: three valid out-pointers for the duration of the call; the ID dhdOpen
        // returned.
        let r = unsafe { (self.api.get_position)(x, y, z, self.id) };
        if r < 0 {
            return Err(self.api.call_error("dhdGetPosition"));
        }
        Ok(p)
    }

    /// The button bitmask (`dhdGetButtonMask`; bit 0 is the first button).
    pub fn buttons(&self) -> u32 {
        // SAFETY: the ID dhdOpen returned.
        unsafe { (self.api.get_button_mask)(self.id) }
    }

    /// Sends a force, newtons, device frame (`dhdSetForce`). A non-finite component sends zero
    /// force instead and returns [`HapticsError::NonFiniteForce`].
    pub fn set_force_n(&mut self, force_n: [f64; 3]) -> Result<ForceStatus, HapticsError> {
        let finite = force_n.iter().all(|f| f.is_finite());
        let [fx, fy, fz] = if finite { force_n } else { [0.0; 3] };
        // SAFETY: the ID dhdOpen returned.
        let r = unsafe { (self.api.set_force)(fx, fy, fz, self.id) };
        if r < 0 {
            return Err(self.api.call_error("dhdSetForce"));
        }
        if !finite {
            return Err(HapticsError::NonFiniteForce { force_n });
        }
        Ok(ForceStatus {
            saturated: r == DHD_MOTOR_SATURATED,
            timeguard: r == DHD_TIMEGUARD,
        })
    }

    /// Closes the device (`dhdClose`).
    pub fn close(mut self) -> Result<(), HapticsError> {
        self.close_inner()
    }

    fn close_inner(&mut self) -> Result<(), HapticsError> {
        if !self.open {
            return Ok(());
        }
        self.open = false;
        // SAFETY: the ID dhdOpen returned, closed only here.
        if unsafe { (self.api.close)(self.id) } < 0 {
            return Err(self.api.call_error("dhdClose"));
        }
        Ok(())
    }
}

impl std::fmt::Debug for DhdDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DhdDevice")
            .field("id", &self.id)
            .field("open", &self.open)
            .finish_non_exhaustive()
    }
}

impl Drop for DhdDevice {
    fn drop(&mut self) {
        // Errors cannot be reported from drop; `close` reports them.
        let _ = self.close_inner();
    }
}

/// `timeout` in units of 125 us, rounded up; `None` beyond 255 units.
fn watchdog_units(timeout: Duration) -> Option<u8> {
    u8::try_from(timeout.as_nanos().div_ceil(WATCHDOG_UNIT_NS)).ok()
}

fn missing(symbol: &'static str) -> HapticsError {
    HapticsError::MissingSymbol {
        library: DHD_SPEC.library.to_owned(),
        symbol,
        detail: "this SDK version does not export it".to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn watchdog_units_round_up_to_125_us() {
        let units = watchdog_units;
        assert_eq!(units(Duration::ZERO), Some(0));
        assert_eq!(units(Duration::from_micros(1)), Some(1));
        assert_eq!(units(Duration::from_millis(1)), Some(8));
        assert_eq!(units(Duration::from_micros(31_875)), Some(255));
        assert_eq!(units(Duration::from_micros(31_876)), None);
    }
}
