//! 3D Systems OpenHaptics HD API (`libHD.so`): Phantom Omni, Touch, Touch X, Premium.
//!
//! [`HdDevice::open`] initialises a device; [`HdDevice::start`] runs a Rust closure as the
//! device's servo loop, an asynchronous callback of the HD scheduler at 1 kHz. The scheduler is
//! one per process: every device's callback runs on it, one after another each tick (the
//! papers' two Phantoms); it starts with the first servo and stops with the last. A trampoline
//! brackets each call with `hdBeginFrame`/`hdEndFrame`, reads the device state in SI units,
//! writes the returned force (clamped to the device's nominal maximum), and collects the errors
//! HD reports, so the closure never touches C.

use std::ffi::{CString, c_char, c_int, c_uint, c_ulong, c_ushort, c_void};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::ptr::NonNull;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::{HapticsError, LibrarySpec, Loaded, c_text, load_library, symbol};

type Hhd = c_uint;
type HdEnum = c_uint;
type HdSchedulerHandle = c_ulong;
type HdCallbackCode = c_uint;
type HdSchedulerCallback = unsafe extern "C" fn(*mut c_void) -> HdCallbackCode;

const HD_INVALID_HANDLE: Hhd = 0xFFFF_FFFF;
const HD_CALLBACK_DONE: HdCallbackCode = 0;
const HD_CALLBACK_CONTINUE: HdCallbackCode = 1;
const HD_DEFAULT_SCHEDULER_PRIORITY: c_ushort = 0x7FFF;

const HD_CURRENT_BUTTONS: HdEnum = 0x2000;
const HD_CURRENT_POSITION: HdEnum = 0x2050;
const HD_CURRENT_VELOCITY: HdEnum = 0x2051;
const HD_NOMINAL_MAX_STIFFNESS: HdEnum = 0x2602;
const HD_NOMINAL_MAX_FORCE: HdEnum = 0x2603;
const HD_CURRENT_FORCE: HdEnum = 0x2700;
const HD_FORCE_OUTPUT: HdEnum = 0x4000;

/// The servo rate asked of the HD scheduler, in hertz.
pub const HD_SCHEDULER_RATE_HZ: u32 = 1000;

/// HD reports lengths in millimetres.
const M_PER_MM: f64 = 1e-3;

/// Errors drained per check: bounds the loop should a library keep reporting.
const MAX_ERRORS_PER_CHECK: usize = 16;

/// HD error codes and names, from the vendor's hdDefines.h (OpenHaptics 3.x).
const HD_ERROR_NAMES: &[(u32, &str)] = &[
    (0x0000, "HD_SUCCESS"),
    (0x0100, "HD_INVALID_ENUM"),
    (0x0101, "HD_INVALID_VALUE"),
    (0x0102, "HD_INVALID_OPERATION"),
    (0x0103, "HD_INVALID_INPUT_TYPE"),
    (0x0104, "HD_BAD_HANDLE"),
    (0x0200, "HD_WARM_MOTORS"),
    (0x0201, "HD_EXCEEDED_MAX_FORCE"),
    (0x0202, "HD_EXCEEDED_MAX_FORCE_IMPULSE"),
    (0x0203, "HD_EXCEEDED_MAX_VELOCITY"),
    (0x0204, "HD_FORCE_ERROR"),
    (0x0300, "HD_DEVICE_FAULT"),
    (0x0301, "HD_DEVICE_ALREADY_INITIATED"),
    (0x0302, "HD_COMM_ERROR"),
    (0x0303, "HD_COMM_CONFIG_ERROR"),
    (0x0304, "HD_TIMER_ERROR"),
    (0x0400, "HD_ILLEGAL_BEGIN"),
    (0x0401, "HD_ILLEGAL_END"),
    (0x0402, "HD_FRAME_ERROR"),
    (0x0500, "HD_INVALID_PRIORITY"),
    (0x0501, "HD_SCHEDULER_FULL"),
    (0x0600, "HD_INVALID_LICENSE"),
];

/// The name hdDefines.h gives an HD error code, e.g. `HD_DEVICE_FAULT` for 0x0300.
pub fn hd_error_name(code: u32) -> Option<&'static str> {
    HD_ERROR_NAMES
        .iter()
        .find(|(c, _)| *c == code)
        .map(|(_, n)| *n)
}

fn error_label(code: u32) -> &'static str {
    hd_error_name(code).unwrap_or("an unknown HD error")
}

static HD_SPEC: LibrarySpec = LibrarySpec {
    library: "libHD.so",
    vendor: "3D Systems OpenHaptics",
    install: "install OpenHaptics for Linux",
    env_var: "VESALIUS_LIBHD",
    names: &["libHD.so", "libHD.so.3.4"],
};

/// `HDErrorInfo`, returned by value by `hdGetError`.
#[repr(C)]
#[derive(Clone, Copy)]
struct RawErrorInfo {
    error_code: c_uint,
    internal_error_code: c_int,
    hhd: Hhd,
}

const _: () = assert!(std::mem::size_of::<RawErrorInfo>() == 12);

/// An error HD reported: its code (see [`hd_error_name`]) and the driver's internal code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HdErrorInfo {
    /// The HD error code, e.g. 0x0300 (`HD_DEVICE_FAULT`).
    pub code: u32,
    /// The driver's internal error code.
    pub internal: i32,
}

impl HdErrorInfo {
    /// The code's name from hdDefines.h, if it is a known one.
    pub fn name(&self) -> Option<&'static str> {
        hd_error_name(self.code)
    }

    /// Packs into a non-zero u64 (the code is never zero for an error).
    fn pack(self) -> u64 {
        (u64::from(self.code) << 32) | u64::from(self.internal as u32)
    }

    fn unpack(v: u64) -> Option<Self> {
        let code = (v >> 32) as u32;
        (code != 0).then_some(Self {
            code,
            internal: v as u32 as i32,
        })
    }
}

/// The HD functions Vesalius calls, as C function pointers into the loaded library.
#[derive(Clone, Copy)]
struct HdApi {
    init_device: unsafe extern "C" fn(*const c_char) -> Hhd,
    disable_device: unsafe extern "C" fn(Hhd),
    make_current_device: unsafe extern "C" fn(Hhd),
    get_error: unsafe extern "C" fn() -> RawErrorInfo,
    get_error_string: unsafe extern "C" fn(c_uint) -> *const c_char,
    enable: unsafe extern "C" fn(HdEnum),
    disable: unsafe extern "C" fn(HdEnum),
    get_doublev: unsafe extern "C" fn(HdEnum, *mut f64),
    get_integerv: unsafe extern "C" fn(HdEnum, *mut c_int),
    set_doublev: unsafe extern "C" fn(HdEnum, *const f64),
    begin_frame: unsafe extern "C" fn(Hhd),
    end_frame: unsafe extern "C" fn(Hhd),
    schedule_asynchronous:
        unsafe extern "C" fn(HdSchedulerCallback, *mut c_void, c_ushort) -> HdSchedulerHandle,
    unschedule: unsafe extern "C" fn(HdSchedulerHandle),
    start_scheduler: unsafe extern "C" fn(),
    stop_scheduler: unsafe extern "C" fn(),
    set_scheduler_rate: unsafe extern "C" fn(c_ulong),
}

impl HdApi {
    fn load(lib: Loaded) -> Result<Self, HapticsError> {
        // SAFETY: each type is the C prototype of the function of that name in OpenHaptics'
        // hd.h (as listed in shared/HAPTICS.md), on x86-64 Linux's C calling convention.
        unsafe {
            Ok(Self {
                init_device: symbol(lib, "hdInitDevice")?,
                disable_device: symbol(lib, "hdDisableDevice")?,
                make_current_device: symbol(lib, "hdMakeCurrentDevice")?,
                get_error: symbol(lib, "hdGetError")?,
                get_error_string: symbol(lib, "hdGetErrorString")?,
                enable: symbol(lib, "hdEnable")?,
                disable: symbol(lib, "hdDisable")?,
                get_doublev: symbol(lib, "hdGetDoublev")?,
                get_integerv: symbol(lib, "hdGetIntegerv")?,
                set_doublev: symbol(lib, "hdSetDoublev")?,
                begin_frame: symbol(lib, "hdBeginFrame")?,
                end_frame: symbol(lib, "hdEndFrame")?,
                schedule_asynchronous: symbol(lib, "hdScheduleAsynchronous")?,
                unschedule: symbol(lib, "hdUnschedule")?,
                start_scheduler: symbol(lib, "hdStartScheduler")?,
                stop_scheduler: symbol(lib, "hdStopScheduler")?,
                set_scheduler_rate: symbol(lib, "hdSetSchedulerRate")?,
            })
        }
    }

    /// Pops the errors HD queued on this thread; returns the first (oldest reported).
    fn drain_errors(&self) -> Option<HdErrorInfo> {
        let mut first = None;
        for _ in 0..MAX_ERRORS_PER_CHECK {
            // SAFETY: hdGetError takes no arguments and returns HDErrorInfo by value.
            let e = unsafe { (self.get_error)() };
            if e.error_code == 0 {
                break;
            }
            first.get_or_insert(HdErrorInfo {
                code: e.error_code,
                internal: e.internal_error_code,
            });
        }
        first
    }

    fn error_string(&self, code: u32) -> String {
        // SAFETY: hdGetErrorString returns a static string (or null) for any code.
        unsafe { c_text((self.get_error_string)(code)) }
            .unwrap_or_else(|| "(no description)".to_owned())
    }

    /// `Err(HdCall)` for the first error HD queued since the last check.
    fn check(&self, call: &'static str) -> Result<(), HapticsError> {
        match self.drain_errors() {
            None => Ok(()),
            Some(e) => Err(HapticsError::HdCall {
                call,
                code: e.code,
                name: error_label(e.code),
                internal: e.internal,
                message: self.error_string(e.code),
            }),
        }
    }

    fn get_double(&self, pname: HdEnum) -> f64 {
        let mut v = [0.0f64; 16];
        // SAFETY: the buffer holds 16 doubles, the most any HD parameter writes.
        unsafe { (self.get_doublev)(pname, v.as_mut_ptr()) };
        v[0]
    }
}

/// The device state handed to the servo callback, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HdState {
    /// Stylus tip position in the device frame, metres (HD reports millimetres).
    pub position_m: [f64; 3],
    /// Stylus tip velocity, m/s (HD reports mm/s).
    pub velocity_m_per_s: [f64; 3],
    /// Button bitmask (bit 0: the first stylus button).
    pub buttons: u32,
    /// The first error HD reported since the previous call, if any: a device fault
    /// (`HD_DEVICE_FAULT`), a force or velocity limit, a communication error. The callback
    /// decides whether to go on; [`HdDevice::check_servo`] reports it to the owner too.
    pub error: Option<HdErrorInfo>,
    /// Calls of the callback so far, this one included (1 on the first call).
    pub tick: u64,
}

/// What the servo callback asks for this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HdCommand {
    /// Render this force (newtons, device frame) and call again next tick. The force is
    /// clamped to the device's nominal maximum; a non-finite one is replaced by zero.
    Continue {
        /// Force in newtons.
        force_n: [f64; 3],
    },
    /// Render zero force and end the servo callback (`HD_CALLBACK_DONE`).
    Stop,
}

/// Where the servo loop stands.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ServoStatus {
    /// The callback is scheduled and has not returned [`HdCommand::Stop`].
    pub running: bool,
    /// Calls of the callback so far.
    pub ticks: u64,
    /// The first error HD reported during the servo, if any.
    pub first_error: Option<HdErrorInfo>,
    /// The callback panicked (the servo then stopped with zero force).
    pub callback_panicked: bool,
}

/// What the servo thread and the device's owner share.
struct ServoShared {
    running: AtomicBool,
    /// The owner asks the callback to end at its next tick (with zero force).
    stop_asked: AtomicBool,
    ticks: AtomicU64,
    /// `HdErrorInfo::pack` of the first error, 0 for none.
    first_error: AtomicU64,
    panicked: AtomicBool,
}

impl ServoShared {
    fn status(&self) -> ServoStatus {
        ServoStatus {
            running: self.running.load(Ordering::Acquire),
            ticks: self.ticks.load(Ordering::Acquire),
            first_error: HdErrorInfo::unpack(self.first_error.load(Ordering::Acquire)),
            callback_panicked: self.panicked.load(Ordering::Acquire),
        }
    }

    fn record_error(&self, e: HdErrorInfo) {
        // Only the first is kept: later ones are usually its consequences.
        let _ = self
            .first_error
            .compare_exchange(0, e.pack(), Ordering::AcqRel, Ordering::Acquire);
    }
}

type ServoCallback = Box<dyn FnMut(&HdState) -> HdCommand + Send>;

/// What the trampoline needs; boxed, handed to HD as `void*`, and only touched by the
/// scheduler thread while scheduled.
struct ServoCtx {
    api: HdApi,
    hhd: Hhd,
    max_force_n: f64,
    callback: ServoCallback,
    shared: Arc<ServoShared>,
    /// An error reported after the last `hdEndFrame`, for the next call's state.
    pending_error: Option<HdErrorInfo>,
}

/// The HD scheduler's asynchronous callback.
unsafe extern "C" fn servo_trampoline(data: *mut c_void) -> HdCallbackCode {
    // SAFETY: `data` is the `ServoCtx` that `HdDevice::start` leaked with `Box::into_raw`; it is
    // freed only after the scheduler stopped and the callback was unscheduled (or finished), and
    // the HD scheduler runs one callback at a time, so this is the only reference to it.
    let ctx = unsafe { &mut *data.cast::<ServoCtx>() };
    servo_tick(ctx)
}

fn servo_tick(ctx: &mut ServoCtx) -> HdCallbackCode {
    let api = ctx.api;
    let mut position_mm = [0.0f64; 16];
    let mut velocity_mm_s = [0.0f64; 16];
    let mut buttons: c_int = 0;
    // SAFETY: plain HD calls on the handle hdInitDevice returned; each buffer holds at least
    // what the parameter writes (3 doubles, one int).
    unsafe {
        (api.make_current_device)(ctx.hhd);
        (api.begin_frame)(ctx.hhd);
        (api.get_doublev)(HD_CURRENT_POSITION, position_mm.as_mut_ptr());
        (api.get_doublev)(HD_CURRENT_VELOCITY, velocity_mm_s.as_mut_ptr());
        (api.get_integerv)(HD_CURRENT_BUTTONS, &mut buttons);
    }
    let error = ctx.pending_error.take().or_else(|| api.drain_errors());
    if let Some(e) = error {
        ctx.shared.record_error(e);
    }
    let tick = ctx.shared.ticks.fetch_add(1, Ordering::AcqRel) + 1;
    if ctx.shared.stop_asked.load(Ordering::Acquire) {
        // SAFETY: HD_CURRENT_FORCE reads 3 doubles, inside the frame begun above.
        unsafe {
            (api.set_doublev)(HD_CURRENT_FORCE, [0.0f64; 3].as_ptr());
            (api.end_frame)(ctx.hhd);
        }
        let _ = api.drain_errors();
        // The last touch of `ctx`: the owner may free it once it reads `running` false.
        ctx.shared.running.store(false, Ordering::Release);
        return HD_CALLBACK_DONE;
    }
    let state = HdState {
        position_m: [0, 1, 2].map(|i| position_mm[i] * M_PER_MM),
        velocity_m_per_s: [0, 1, 2].map(|i| velocity_mm_s[i] * M_PER_MM),
        buttons: buttons as u32,
        error,
        tick,
    };
    // No panic may cross into C. After one, the callback is never called again, so state it
    // left half-updated is never observed: asserting unwind safety is sound.
    let command = catch_unwind(AssertUnwindSafe(|| (ctx.callback)(&state)));
    let (force_n, code) = match command {
        Ok(HdCommand::Continue { force_n }) => {
            (limit_force(force_n, ctx.max_force_n), HD_CALLBACK_CONTINUE)
        }
        Ok(HdCommand::Stop) => ([0.0; 3], HD_CALLBACK_DONE),
        Err(_) => {
            ctx.shared.panicked.store(true, Ordering::Release);
            ([0.0; 3], HD_CALLBACK_DONE)
        }
    };
    // SAFETY: HD_CURRENT_FORCE reads 3 doubles from the array, inside the frame begun above.
    unsafe {
        (api.set_doublev)(HD_CURRENT_FORCE, force_n.as_ptr());
        (api.end_frame)(ctx.hhd);
    }
    if let Some(e) = api.drain_errors() {
        ctx.shared.record_error(e);
        ctx.pending_error = Some(e);
    }
    if code == HD_CALLBACK_DONE {
        ctx.shared.running.store(false, Ordering::Release);
    }
    code
}

/// Zero for a non-finite force; otherwise the force scaled down to `max_n` if longer.
fn limit_force(force_n: [f64; 3], max_n: f64) -> [f64; 3] {
    if force_n.iter().any(|f| !f.is_finite()) {
        return [0.0; 3];
    }
    let norm = force_n.iter().map(|f| f * f).sum::<f64>().sqrt();
    if max_n.is_finite() && max_n > 0.0 && norm > max_n {
        force_n.map(|f| f * (max_n / norm))
    } else {
        force_n
    }
}

/// The HD scheduler is one per process: how many servos are scheduled on it. Held while a
/// servo is added or removed, so the scheduler starts with the first and stops with the last.
static SCHEDULER_USERS: Mutex<usize> = Mutex::new(0);

/// How long [`HdDevice::stop`] waits for a callback asked to end while other servos keep the
/// scheduler running (a few hundred ticks), before it unschedules it.
const STOP_WAIT: Duration = Duration::from_millis(250);

fn scheduler_users() -> std::sync::MutexGuard<'static, usize> {
    // A panic while holding the count leaves it right (it is changed last): go on.
    SCHEDULER_USERS
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A running servo: the context handed to HD and what the owner reads.
struct Servo {
    ctx: NonNull<ServoCtx>,
    handle: HdSchedulerHandle,
    shared: Arc<ServoShared>,
}

/// An initialised OpenHaptics device. Dropping it stops its servo and disables it.
///
/// `Send` (every HD call made here first makes this device current, so the owning thread may
/// change) but not `Sync`: use it from one thread at a time.
pub struct HdDevice {
    api: HdApi,
    hhd: Hhd,
    nominal_max_force_n: f64,
    nominal_max_stiffness_n_per_m: f64,
    servo: Option<Servo>,
    last_status: ServoStatus,
    disabled: bool,
}

// SAFETY: the only non-Send field is the servo context pointer; the context is owned by this
// device (its closure is `Send`), and while scheduled only the scheduler thread touches it.
unsafe impl Send for HdDevice {}

impl HdDevice {
    /// Loads libHD (see the module documentation for the lookup) and initialises the device
    /// named `name` in Touch_Setup, or the default device for `None`.
    pub fn open(name: Option<&str>) -> Result<Self, HapticsError> {
        Self::open_with(load_library(&HD_SPEC, None)?, name)
    }

    /// Like [`HdDevice::open`] with the library at `library` (no search).
    pub fn open_from(library: &Path, name: Option<&str>) -> Result<Self, HapticsError> {
        Self::open_with(load_library(&HD_SPEC, Some(library))?, name)
    }

    fn open_with(lib: Loaded, name: Option<&str>) -> Result<Self, HapticsError> {
        let api = HdApi::load(lib)?;
        let c_name = name
            .map(|n| {
                CString::new(n).map_err(|_| HapticsError::InvalidDeviceName { name: n.into() })
            })
            .transpose()?;
        let device = name.unwrap_or("HD_DEFAULT_DEVICE").to_owned();
        // Errors left by earlier calls on this thread would be blamed on this one.
        let _ = api.drain_errors();
        let name_ptr = c_name.as_ref().map_or(std::ptr::null(), |n| n.as_ptr());
        // SAFETY: `name_ptr` is null (HD_DEFAULT_DEVICE) or a NUL-terminated string that
        // outlives the call.
        let hhd = unsafe { (api.init_device)(name_ptr) };
        let init_error = api.drain_errors();
        if let Some(e) = init_error {
            if hhd != HD_INVALID_HANDLE {
                // SAFETY: a handle hdInitDevice returned.
                unsafe { (api.disable_device)(hhd) };
            }
            return Err(HapticsError::HdInit {
                device,
                code: e.code,
                name: error_label(e.code),
                internal: e.internal,
                message: api.error_string(e.code),
            });
        }
        if hhd == HD_INVALID_HANDLE {
            return Err(HapticsError::HdInit {
                device,
                code: 0,
                name: "HD_SUCCESS",
                internal: 0,
                message: "it returned HD_INVALID_HANDLE without reporting an error".into(),
            });
        }
        let mut dev = Self {
            api,
            hhd,
            nominal_max_force_n: 0.0,
            nominal_max_stiffness_n_per_m: 0.0,
            servo: None,
            last_status: ServoStatus::default(),
            disabled: false,
        };
        dev.make_current();
        dev.nominal_max_force_n = api.get_double(HD_NOMINAL_MAX_FORCE);
        // N/mm -> N/m.
        dev.nominal_max_stiffness_n_per_m = api.get_double(HD_NOMINAL_MAX_STIFFNESS) * 1e3;
        // On error `dev` drops here, which disables the device.
        api.check("hdGetDoublev(HD_NOMINAL_MAX_FORCE, HD_NOMINAL_MAX_STIFFNESS)")?;
        Ok(dev)
    }

    fn make_current(&self) {
        // SAFETY: a handle hdInitDevice returned and that is not disabled.
        unsafe { (self.api.make_current_device)(self.hhd) };
    }

    /// The HD device handle.
    pub fn handle(&self) -> u32 {
        self.hhd
    }

    /// The device's nominal maximum force, newtons (`HD_NOMINAL_MAX_FORCE`). The servo clamps
    /// every force to it.
    pub fn nominal_max_force_n(&self) -> f64 {
        self.nominal_max_force_n
    }

    /// The device's nominal maximum stiffness, N/m (`HD_NOMINAL_MAX_STIFFNESS`, which HD
    /// reports in N/mm).
    pub fn nominal_max_stiffness_n_per_m(&self) -> f64 {
        self.nominal_max_stiffness_n_per_m
    }

    /// Turns the motors' force output on (`hdEnable(HD_FORCE_OUTPUT)`).
    pub fn enable_force_output(&mut self) -> Result<(), HapticsError> {
        self.make_current();
        // SAFETY: a capability constant from hdDefines.h.
        unsafe { (self.api.enable)(HD_FORCE_OUTPUT) };
        self.api.check("hdEnable(HD_FORCE_OUTPUT)")
    }

    /// Turns the motors' force output off (`hdDisable(HD_FORCE_OUTPUT)`).
    pub fn disable_force_output(&mut self) -> Result<(), HapticsError> {
        self.make_current();
        // SAFETY: a capability constant from hdDefines.h.
        unsafe { (self.api.disable)(HD_FORCE_OUTPUT) };
        self.api.check("hdDisable(HD_FORCE_OUTPUT)")
    }

    /// Runs `callback` as the servo loop: the HD scheduler calls it at
    /// [`HD_SCHEDULER_RATE_HZ`] on its own thread with the device state, and renders the force
    /// it returns, until it returns [`HdCommand::Stop`] or [`HdDevice::stop`] is called. The
    /// callback must not block: it runs inside the device's servo frame.
    pub fn start<F>(&mut self, callback: F) -> Result<(), HapticsError>
    where
        F: FnMut(&HdState) -> HdCommand + Send + 'static,
    {
        if let Some(servo) = &self.servo {
            if servo.shared.running.load(Ordering::Acquire) {
                return Err(HapticsError::ServoRunning);
            }
            // The previous callback returned Stop: release its context.
            self.stop()?;
        }
        let mut users = scheduler_users();
        self.schedule(Box::new(callback), *users == 0)?;
        *users += 1;
        Ok(())
    }

    /// Schedules the callback, and starts the scheduler when `first`.
    fn schedule(&mut self, callback: ServoCallback, first: bool) -> Result<(), HapticsError> {
        let api = self.api;
        self.make_current();
        let _ = api.drain_errors();
        // SAFETY: a plain HD call.
        unsafe { (api.set_scheduler_rate)(c_ulong::from(HD_SCHEDULER_RATE_HZ)) };
        api.check("hdSetSchedulerRate")?;
        let shared = Arc::new(ServoShared {
            running: AtomicBool::new(true),
            stop_asked: AtomicBool::new(false),
            ticks: AtomicU64::new(0),
            first_error: AtomicU64::new(0),
            panicked: AtomicBool::new(false),
        });
        let ctx = Box::new(ServoCtx {
            api,
            hhd: self.hhd,
            max_force_n: self.nominal_max_force_n,
            callback,
            shared: Arc::clone(&shared),
            pending_error: None,
        });
        let ctx = NonNull::from(Box::leak(ctx));
        // SAFETY: the trampoline has HDSchedulerCallback's signature and `ctx` stays valid until
        // `stop` (or the error paths below) take it back, after the callback can no longer run.
        let handle = unsafe {
            (api.schedule_asynchronous)(
                servo_trampoline,
                ctx.as_ptr().cast(),
                HD_DEFAULT_SCHEDULER_PRIORITY,
            )
        };
        if let Err(e) = api.check("hdScheduleAsynchronous") {
            // SAFETY: HD refused the callback, so nothing refers to `ctx`.
            drop(unsafe { Box::from_raw(ctx.as_ptr()) });
            return Err(e);
        }
        if !first {
            // The scheduler runs (another device's servo started it).
            self.servo = Some(Servo {
                ctx,
                handle,
                shared,
            });
            return Ok(());
        }
        // SAFETY: a plain HD call.
        unsafe { (api.start_scheduler)() };
        if let Err(e) = api.check("hdStartScheduler") {
            // SAFETY: the scheduler did not start, so the callback is not running; after
            // hdUnschedule it never will, and nothing else refers to `ctx`.
            unsafe {
                (api.stop_scheduler)();
                (api.unschedule)(handle);
                drop(Box::from_raw(ctx.as_ptr()));
            }
            let _ = api.drain_errors();
            return Err(e);
        }
        self.servo = Some(Servo {
            ctx,
            handle,
            shared,
        });
        Ok(())
    }

    /// Where the servo stands (the final status once stopped).
    pub fn servo_status(&self) -> ServoStatus {
        match &self.servo {
            Some(s) => s.shared.status(),
            None => self.last_status,
        }
    }

    /// `Err` once the servo saw a device error ([`HapticsError::DeviceFault`], naming the HD
    /// code) or its callback panicked; for the owner to poll and stop.
    pub fn check_servo(&self) -> Result<(), HapticsError> {
        let status = self.servo_status();
        if let Some(e) = status.first_error {
            return Err(HapticsError::DeviceFault {
                code: e.code,
                name: error_label(e.code),
                internal: e.internal,
                message: self.api.error_string(e.code),
            });
        }
        if status.callback_panicked {
            return Err(HapticsError::CallbackPanicked);
        }
        Ok(())
    }

    /// Stops the servo and frees its callback; returns the final status. The last servo on
    /// the scheduler stops it (which waits for the running callback) and then unschedules its
    /// callback if that had not returned Stop. A servo beside others asks its callback to end
    /// at the next tick (with zero force) and waits for that, so the others never miss a tick;
    /// should the scheduler not come round within [`STOP_WAIT`], it unschedules the callback.
    /// Does nothing when no servo runs.
    pub fn stop(&mut self) -> Result<ServoStatus, HapticsError> {
        let Some(servo) = self.servo.take() else {
            return Ok(self.last_status);
        };
        let api = self.api;
        let mut users = scheduler_users();
        let last = *users <= 1;
        if last {
            // SAFETY: a plain HD call; it returns once the scheduler thread is stopped.
            unsafe { (api.stop_scheduler)() };
        } else {
            servo.shared.stop_asked.store(true, Ordering::Release);
            let asked = Instant::now();
            while servo.shared.running.load(Ordering::Acquire) && asked.elapsed() < STOP_WAIT {
                std::thread::sleep(Duration::from_micros(200));
            }
        }
        let status = servo.shared.status();
        if status.running {
            // SAFETY: the handle hdScheduleAsynchronous returned, for a callback that has not
            // finished (HD forgets the handle of one that returned DONE); hdUnschedule returns
            // once the callback is not running and never will again.
            unsafe { (api.unschedule)(servo.handle) };
        }
        // SAFETY: `ctx` came from `Box::leak` in `schedule`; the callback finished (its last
        // touch of the context was to say so) or is unscheduled, or the scheduler is stopped,
        // so nothing refers to it any more.
        drop(unsafe { Box::from_raw(servo.ctx.as_ptr()) });
        *users = users.saturating_sub(1);
        drop(users);
        self.last_status = ServoStatus {
            running: false,
            ..status
        };
        api.check("hdStopScheduler/hdUnschedule")?;
        Ok(self.last_status)
    }

    /// Stops the servo and disables the device (`hdDisableDevice`).
    pub fn close(mut self) -> Result<(), HapticsError> {
        let stopped = self.stop();
        self.disable();
        stopped?;
        self.api.check("hdDisableDevice")
    }

    fn disable(&mut self) {
        if !self.disabled {
            self.disabled = true;
            // SAFETY: a handle hdInitDevice returned, disabled only here.
            unsafe { (self.api.disable_device)(self.hhd) };
        }
    }
}

impl std::fmt::Debug for HdDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HdDevice")
            .field("handle", &self.hhd)
            .field("nominal_max_force_n", &self.nominal_max_force_n)
            .field(
                "nominal_max_stiffness_n_per_m",
                &self.nominal_max_stiffness_n_per_m,
            )
            .field("servo", &self.servo_status())
            .finish_non_exhaustive()
    }
}

impl Drop for HdDevice {
    fn drop(&mut self) {
        // Errors cannot be reported from drop; `close` reports them.
        let _ = self.stop();
        self.disable();
        let _ = self.api.drain_errors();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_is_clamped_to_the_nominal_maximum_and_never_non_finite() {
        assert_eq!(limit_force([1.5, -0.5, 0.0], 3.3), [1.5, -0.5, 0.0]);
        let f = limit_force([6.0, 0.0, 8.0], 3.3);
        assert!((f[0] - 1.98).abs() < 1e-12 && (f[2] - 2.64).abs() < 1e-12);
        assert_eq!(limit_force([f64::NAN, 0.0, 1.0], 3.3), [0.0; 3]);
        assert_eq!(limit_force([f64::INFINITY, 0.0, 1.0], 3.3), [0.0; 3]);
        // No nominal maximum known: no clamp.
        assert_eq!(limit_force([10.0, 0.0, 0.0], 0.0), [10.0, 0.0, 0.0]);
    }

    #[test]
    fn error_info_round_trips_through_its_packed_form() {
        let e = HdErrorInfo {
            code: 0x0300,
            internal: -17,
        };
        assert_eq!(HdErrorInfo::unpack(e.pack()), Some(e));
        assert_eq!(HdErrorInfo::unpack(0), None);
        assert_eq!(e.name(), Some("HD_DEVICE_FAULT"));
        assert_eq!(hd_error_name(0x0302), Some("HD_COMM_ERROR"));
        assert_eq!(hd_error_name(0x0600), Some("HD_INVALID_LICENSE"));
        assert_eq!(hd_error_name(0x0999), None);
    }
}
