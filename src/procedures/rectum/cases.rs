//! The rectum's reference cases that need its whole scene: the membrane handing a load on its
//! fat to the rod through the skin.

use super::{Anatomy, AnatomyParams, RectumScene, SceneParams, ToolState};
use crate::models::membrane::LAYERS;
use crate::sim::{Case, Measured};
use glam::Vec3;

/// `vesalius verify`'s rows for the coupled scene.
pub fn cases() -> Vec<Case> {
    vec![Case {
        model: "rectum scene",
        case: "membrane_load_on_rod",
        description: "50 mN pressing on the fat (layer 1, 5 x 5 nodes) over the middle of a \
                          coarse rectum (60 x 48 a layer), every tile awake, the pelvic side let \
                          go so the membrane hangs on the rod alone: the membrane's load on the \
                          rod after 0.8 s vs the load (at rest a free membrane passes it all \
                          on); tolerance 5 %",
        unit: "N",
        tolerance: 0.05,
        run: load_on_rod,
    }]
}

/// `vesalius verify --compute gpu`'s rows for the coupled scene: the same case with the
/// membrane's substeps on the GPU.
pub fn gpu_cases() -> Vec<Case> {
    vec![Case {
        model: "rectum scene, gpu",
        case: "membrane_load_on_rod_gpu",
        description: "membrane_load_on_rod with the membrane's substeps on the first Vulkan \
                      adapter (every tile awake: the whole membrane's kernel, its state up and \
                      back each step): the membrane's load on the rod after 0.8 s vs the load; \
                      tolerance 5 %, as on the CPU",
        unit: "N",
        tolerance: 0.05,
        run: || load_on_rod_on(true),
    }]
}

/// `vesalius verify --preset cpu`'s rows: the coupled case on the CPU preset's membrane.
pub fn preset_cases() -> Vec<Case> {
    vec![Case {
        model: "rectum scene",
        case: "membrane_load_on_rod_preset",
        description: "membrane_load_on_rod on the membrane of the cpu preset \
                      (assets/presets/cpu/rectum.toml as shipped: 90 x 60 a layer, its \
                      springs' and links' damping), every tile awake: the membrane's load on the rod \
                      after 0.8 s vs the load; tolerance 5 %",
        unit: "N",
        tolerance: 0.05,
        run: || match preset_scene() {
            Some((grid, params)) => load_on_rod_at(grid, params, false),
            None => Measured::not_run(0.05),
        },
    }]
}

/// The CPU preset's membrane, rows x columns a layer, and the scene's parameters it makes
/// (None: no preset, or one that does not make a valid scenario).
fn preset_scene() -> Option<((u32, u32), SceneParams)> {
    let (file, text) = super::INFO.cpu_preset_scenario()?.ok()?;
    let s = super::Scenario::parse(&file, &text).ok()?;
    let a = s.anatomy_params();
    Some(((a.rows, a.cols), s.scene_params()))
}

fn load_on_rod() -> Measured {
    load_on_rod_on(false)
}

/// The case, with the membrane on the GPU where `on_gpu` (not run without an adapter).
fn load_on_rod_on(on_gpu: bool) -> Measured {
    load_on_rod_at((60, 48), SceneParams::default(), on_gpu)
}

/// The case on a rectum of `grid` (rows x columns a layer) with `params`.
fn load_on_rod_at(grid: (u32, u32), params: SceneParams, on_gpu: bool) -> Measured {
    let load = Vec3::new(0.0, -0.05, 0.0);
    let reference = f64::from(load.length());
    let Ok(a) = Anatomy::generate(AnatomyParams {
        rows: grid.0,
        cols: grid.1,
        ..AnatomyParams::default()
    }) else {
        return Measured::not_run(reference);
    };
    let Ok(mut s) = RectumScene::new(&a, params) else {
        return Measured::not_run(reference);
    };
    s.membrane_mut().detach_layer(LAYERS - 1);
    s.membrane_mut().stay_awake();
    if on_gpu {
        let on = crate::gpu::Gpu::headless(false).and_then(|gpu| s.membrane_mut().use_gpu(&gpu));
        if on.is_err() {
            return Measured::not_run(reference);
        }
    }
    let patch = s.top_patch(1, 2);
    let idle = ToolState {
        hook: None,
        cutting: false,
        grasper: None,
        grasper_right: None,
    };
    let steps = 800;
    let mut on_rod = Vec3::ZERO;
    for _ in 0..steps {
        for &n in &patch {
            s.membrane_mut().add_force(n, load / patch.len() as f32);
        }
        on_rod = s.step(1e-3, &idle, 0, &mut Vec::new()).membrane_on_rod_n;
    }
    if on_gpu && s.membrane().gpu_adapter().is_none() {
        // The device failed on the way: the CPU finished the case, so the GPU did not pass it.
        return Measured::not_run(reference);
    }
    // The load's component along itself: what the rod takes of it.
    let along = on_rod.as_dvec3().dot(load.as_dvec3().normalize());
    Measured {
        reference,
        measured: along,
        simulated_s: steps as f64 * 1e-3,
        floor: 0.0,
    }
}
