//! Swapchains (their images are `gpu.rs`'s), and the frame dumps: at every Nth `xrEndFrame`
//! the runtime copies each projection view's sub-image back on the session's queue and writes
//! it as `frames/NNNN_left.png` / `NNNN_right.png`.

use crate::ffi::{arg, arg_mut, two_call, xr_try};
use crate::gpu::{FORMATS, Swapchain};
use crate::state::{Runtime, live, result, with_session};
use crate::system::SESSION;
use ash::vk::Handle as _;
use openxr_sys as sys;
use sys::Handle as _;

const TAG: u64 = 4 << 32;

fn index(h: sys::Swapchain) -> Option<usize> {
    let raw = h.into_raw();
    (raw & !0xffff_ffff == TAG && raw & 0xffff_ffff != 0).then(|| (raw & 0xffff_ffff) as usize - 1)
}

/// The session's swapchain behind a handle.
fn chain(rt: &mut Runtime, h: sys::Swapchain) -> Result<&mut Swapchain, sys::Result> {
    let s = live(rt)?;
    index(h)
        .and_then(|k| s.swapchains.get_mut(k))
        .and_then(Option::as_mut)
        .ok_or(sys::Result::ERROR_HANDLE_INVALID)
}

pub(crate) fn lookup(name: &str) -> Option<sys::pfn::VoidFunction> {
    // SAFETY (all transmutes): each turns a function pointer of the exact pfn type OpenXR
    // declares for that name into PFN_xrVoidFunction; the caller casts it back before calling.
    unsafe {
        use std::mem::transmute;
        use sys::pfn::VoidFunction as V;
        match name {
            "xrEnumerateSwapchainFormats" => {
                Some(transmute::<sys::pfn::EnumerateSwapchainFormats, V>(formats))
            }
            "xrCreateSwapchain" => Some(transmute::<sys::pfn::CreateSwapchain, V>(create)),
            "xrDestroySwapchain" => Some(transmute::<sys::pfn::DestroySwapchain, V>(destroy)),
            "xrEnumerateSwapchainImages" => {
                Some(transmute::<sys::pfn::EnumerateSwapchainImages, V>(images))
            }
            "xrAcquireSwapchainImage" => {
                Some(transmute::<sys::pfn::AcquireSwapchainImage, V>(acquire))
            }
            "xrWaitSwapchainImage" => Some(transmute::<sys::pfn::WaitSwapchainImage, V>(wait)),
            "xrReleaseSwapchainImage" => {
                Some(transmute::<sys::pfn::ReleaseSwapchainImage, V>(release))
            }
            _ => None,
        }
    }
}

unsafe extern "system" fn formats(
    session: sys::Session,
    capacity: u32,
    count: *mut u32,
    out: *mut i64,
) -> sys::Result {
    xr_try!(with_session(session, |rt| live(rt).map(|_| ())));
    let list: Vec<i64> = FORMATS.iter().map(|f| i64::from(f.as_raw())).collect();
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe { two_call(capacity, count, out, &list, |a, b| *b = *a) }
}

unsafe extern "system" fn create(
    session: sys::Session,
    info: *const sys::SwapchainCreateInfo,
    out: *mut sys::Swapchain,
) -> sys::Result {
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the caller passes a writable handle or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    if !FORMATS.iter().any(|f| i64::from(f.as_raw()) == info.format) {
        return sys::Result::ERROR_SWAPCHAIN_FORMAT_UNSUPPORTED;
    }
    let sizes_ok = (1..=4096).contains(&info.width)
        && (1..=4096).contains(&info.height)
        && (1..=16).contains(&info.array_size)
        && info.face_count == 1
        && info.mip_count == 1
        && info.sample_count == 1;
    if !sizes_ok {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    let h = xr_try!(with_session(session, |rt| {
        let s = live(rt)?;
        let dev = s
            .device
            .as_ref()
            .ok_or(sys::Result::ERROR_RUNTIME_FAILURE)?;
        let made = Swapchain::create(dev, info)?;
        s.swapchains.push(Some(made));
        Ok(TAG | s.swapchains.len() as u64)
    }));
    *out = sys::Swapchain::from_raw(h);
    sys::Result::SUCCESS
}

unsafe extern "system" fn destroy(h: sys::Swapchain) -> sys::Result {
    result(with_session(sys::Session::from_raw(SESSION), |rt| {
        let s = live(rt)?;
        let slot = index(h)
            .and_then(|k| s.swapchains.get_mut(k))
            .filter(|c| c.is_some())
            .ok_or(sys::Result::ERROR_HANDLE_INVALID)?;
        if let (Some(mut c), Some(dev)) = (slot.take(), s.device.as_ref()) {
            c.destroy(dev);
        }
        Ok(())
    }))
}

unsafe extern "system" fn images(
    h: sys::Swapchain,
    capacity: u32,
    count: *mut u32,
    out: *mut sys::SwapchainImageBaseHeader,
) -> sys::Result {
    let list = xr_try!(with_session(sys::Session::from_raw(SESSION), |rt| Ok(
        chain(rt, h)?
            .images
            .iter()
            .map(|i| i.image.as_raw())
            .collect::<Vec<u64>>()
    )));
    if count.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: `count` is non-null and writable.
    unsafe { *count = list.len() as u32 };
    if capacity == 0 {
        return sys::Result::SUCCESS;
    }
    if (capacity as usize) < list.len() || out.is_null() {
        return sys::Result::ERROR_SIZE_INSUFFICIENT;
    }
    let out = out.cast::<sys::SwapchainImageVulkanKHR>();
    for (k, image) in list.into_iter().enumerate() {
        // SAFETY: for a Vulkan session the app passes an array of `capacity` (>= count)
        // XrSwapchainImageVulkanKHR structures.
        let slot = unsafe { &mut *out.add(k) };
        if slot.ty != sys::SwapchainImageVulkanKHR::TYPE {
            return sys::Result::ERROR_VALIDATION_FAILURE;
        }
        slot.image = image;
    }
    sys::Result::SUCCESS
}

unsafe extern "system" fn acquire(
    h: sys::Swapchain,
    _info: *const sys::SwapchainImageAcquireInfo,
    out: *mut u32,
) -> sys::Result {
    // SAFETY: the caller passes a writable index or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    let k = xr_try!(with_session(sys::Session::from_raw(SESSION), |rt| {
        let c = chain(rt, h)?;
        if c.acquired.len() >= c.images.len() {
            return Err(sys::Result::ERROR_CALL_ORDER_INVALID);
        }
        let k = c.next;
        c.next = (c.next + 1) % c.images.len();
        c.acquired.push_back(k);
        Ok(k)
    }));
    *out = k as u32;
    sys::Result::SUCCESS
}

unsafe extern "system" fn wait(
    h: sys::Swapchain,
    _info: *const sys::SwapchainImageWaitInfo,
) -> sys::Result {
    result(with_session(sys::Session::from_raw(SESSION), |rt| {
        let c = chain(rt, h)?;
        if c.waited.is_some() {
            return Err(sys::Result::ERROR_CALL_ORDER_INVALID);
        }
        c.waited = Some(
            *c.acquired
                .front()
                .ok_or(sys::Result::ERROR_CALL_ORDER_INVALID)?,
        );
        Ok(())
    }))
}

unsafe extern "system" fn release(
    h: sys::Swapchain,
    _info: *const sys::SwapchainImageReleaseInfo,
) -> sys::Result {
    result(with_session(sys::Session::from_raw(SESSION), |rt| {
        let c = chain(rt, h)?;
        let k = c
            .waited
            .take()
            .ok_or(sys::Result::ERROR_CALL_ORDER_INVALID)?;
        c.acquired.pop_front();
        c.released = Some(k);
        Ok(())
    }))
}

/// A projection view to dump: which swapchain, layer and rectangle.
pub(crate) struct ViewImage {
    pub(crate) swapchain: sys::Swapchain,
    pub(crate) layer: u32,
    pub(crate) rect: sys::Rect2Di,
}

/// Checks the views' swapchains are the session's and have released an image.
pub(crate) fn check_views(rt: &mut Runtime, views: &[ViewImage]) -> Result<(), sys::Result> {
    for v in views {
        let c = chain(rt, v.swapchain).map_err(|_| sys::Result::ERROR_LAYER_INVALID)?;
        if c.released.is_none() || v.layer >= c.layers {
            return Err(sys::Result::ERROR_LAYER_INVALID);
        }
    }
    Ok(())
}

/// Writes `frames/NNNN_left.png` and `NNNN_right.png` from a frame's two views.
pub(crate) fn dump_views(rt: &mut Runtime, frame: u64, views: &[ViewImage]) {
    let Some(dir) = rt.config.as_ref().and_then(|c| c.out_dir.clone()) else {
        return;
    };
    let Some(s) = rt.session.as_ref() else {
        return;
    };
    let Some(dev) = s.device.as_ref() else {
        return;
    };
    for (v, eye) in views.iter().zip(["left", "right"]) {
        let Some(Some(c)) = index(v.swapchain).and_then(|k| s.swapchains.get(k)) else {
            continue;
        };
        let Some(image) = c.released else {
            continue;
        };
        let path = dir.join("frames").join(format!("{frame:04}_{eye}.png"));
        if let Err(e) = c.dump(dev, image, v.layer, v.rect, &path) {
            eprintln!("vesalius-sim-runtime: {}: {e}", path.display());
        }
    }
}
