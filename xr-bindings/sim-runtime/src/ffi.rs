//! Helpers for the C interface that every entry point shares: `xr_try!`, checked pointer
//! arguments, and the two-call idiom. Nothing here knows the runtime's state.

use openxr_sys as sys;
use std::ffi::c_char;

/// `?` for functions that return an `XrResult`: the error code is returned as it is.
macro_rules! xr_try {
    ($e:expr) => {
        match $e {
            Ok(v) => v,
            Err(code) => return code,
        }
    };
}
pub(crate) use xr_try;

/// Copies `s` into a fixed C string buffer, truncated and NUL-terminated.
pub(crate) fn write_c(dst: &mut [c_char], s: &str) {
    let n = s.len().min(dst.len().saturating_sub(1));
    for (d, b) in dst.iter_mut().zip(s.bytes().take(n)) {
        *d = b as c_char;
    }
    if let Some(end) = dst.get_mut(n) {
        *end = 0;
    }
}

/// An input structure the caller passed: null is a validation failure.
///
/// # Safety
/// `p` must be null or point to a valid `T` that outlives `'a`.
pub(crate) unsafe fn arg<'a, T>(p: *const T) -> Result<&'a T, sys::Result> {
    // SAFETY: `p` is null or valid (caller's contract).
    unsafe { p.as_ref() }.ok_or(sys::Result::ERROR_VALIDATION_FAILURE)
}

/// An output structure the caller passed: null is a validation failure.
///
/// # Safety
/// `p` must be null or point to a writable `T`, not aliased, that outlives `'a`.
pub(crate) unsafe fn arg_mut<'a, T>(p: *mut T) -> Result<&'a mut T, sys::Result> {
    // SAFETY: `p` is null or valid and unaliased (caller's contract).
    unsafe { p.as_mut() }.ok_or(sys::Result::ERROR_VALIDATION_FAILURE)
}

/// Fills a two-call-idiom array: writes the count, and the items when there is room.
///
/// # Safety
/// `count` must be writable; `out` must hold `capacity` items when `capacity` > 0.
pub(crate) unsafe fn two_call<T>(
    capacity: u32,
    count: *mut u32,
    out: *mut T,
    items: &[T],
    copy: impl Fn(&T, &mut T),
) -> sys::Result {
    if count.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: `count` is non-null and writable (caller's contract).
    unsafe { *count = items.len() as u32 };
    if capacity == 0 {
        return sys::Result::SUCCESS;
    }
    if (capacity as usize) < items.len() || out.is_null() {
        return sys::Result::ERROR_SIZE_INSUFFICIENT;
    }
    for (k, item) in items.iter().enumerate() {
        // SAFETY: `out` holds at least `capacity` >= items.len() elements (caller's contract).
        copy(item, unsafe { &mut *out.add(k) });
    }
    sys::Result::SUCCESS
}
