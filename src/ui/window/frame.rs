//! One window frame: the 3D view into its texture, the panels over the swapchain, the
//! mouse over the view, and the screenshot.

use super::*;

impl App {
    pub(super) fn redraw(&mut self, el: &ActiveEventLoop) -> Result<(), WindowError> {
        let t0 = Instant::now();
        if self.sim.as_ref().is_some_and(SimThread::finished) {
            self.end_session()?;
        }
        let Some(v) = self.view.as_mut() else {
            return Ok(());
        };
        // The newest simulation state (a free camera under XR takes a snapshot of its own).
        // After the session, the last mirrored frame stays on screen.
        let mirrored = matches!(self.view_mode, ViewMode::Eye(_))
            && (self.mirror_id.is_some() || self.xr.is_some());
        let snapshot = match (&self.sim, self.xr.as_mut()) {
            (Some(sim), _) => {
                self.dashboard.update((**sim.status.load()).clone());
                Some(sim.bus.latest())
            }
            (None, Some(x)) => {
                self.dashboard.update((*x.status()).clone());
                (!mirrored).then(|| x.snapshot())
            }
            _ => None,
        };
        if self.mirror_id.is_none()
            && let Some(m) = self.xr.as_ref().and_then(|x| x.mirror.as_ref())
        {
            self.mirror_id = Some(v.painter.register_native_texture(
                &v.gpu.device,
                &m.view,
                wgpu::FilterMode::Linear,
            ));
            self.mirror_size = m.size;
        }
        let mirror = self
            .mirror_id
            .map(|id| (self.mirror_size, id))
            .filter(|_| mirrored);
        self.dashboard.viewing = self.xr.is_some().then_some(match self.view_mode {
            ViewMode::Eye(MirrorEye::Left) => "the headset's left eye",
            ViewMode::Eye(MirrorEye::Right) => "the headset's right eye",
            ViewMode::Free => "a free camera",
        });
        if let Some(s) = &snapshot
            && v.last_step != Some(s.step)
        {
            v.renderer.update(s);
            v.last_step = Some(s.step);
        }
        // The laparoscope moved by the trainee's device: the free camera goes there.
        if let Some(scope) = snapshot.as_ref().and_then(|s| s.scope)
            && self.scope_seen != Some(scope)
        {
            self.camera = OrbitCamera::looking(scope.eye, scope.target);
            self.scope_seen = Some(scope);
        }
        // The procedure's own picture: a texture of its grey, made again when it changes.
        let picture = snapshot.as_ref().and_then(|s| s.picture.clone());
        match (&picture, &mut self.picture) {
            (Some(p), Some((seen, handle))) if !Arc::ptr_eq(p, seen) => {
                handle.set(grey_image(p), egui::TextureOptions::LINEAR);
                *seen = p.clone();
            }
            (Some(p), None) => {
                let handle = v.egui.egui_ctx().load_texture(
                    "procedure picture",
                    grey_image(p),
                    egui::TextureOptions::LINEAR,
                );
                self.picture = Some((p.clone(), handle));
            }
            _ => {}
        }
        let shown_picture = self
            .picture
            .as_ref()
            .filter(|_| !self.teaching_view && mirror.is_none())
            .map(|(p, h)| (h.id(), (p.width as f32, p.height as f32)));
        // Panels first: they decide how large the 3D view is.
        let input = v.egui.take_egui_input(&v.window);
        let ppp = v.egui.egui_ctx().pixels_per_point();
        let mut view_px = (1u32, 1u32);
        let mut pointer = Pointer::default();
        let scene_id = v.scene.as_ref().map(|s| s.id);
        self.dashboard.driving = self.desktop.as_ref().map(|(h, _)| match h.selected {
            Hand::Left => "the grasper",
            Hand::Right => "the laser",
        });
        let dashboard = &mut self.dashboard;
        let mut actions = Default::default();
        let trainer = self.trainer;
        let mut screen = super::super::screens::ScreenActions::default();
        let ui_start = Instant::now();
        let out = v.egui.egui_ctx().clone().run_ui(input, |ui| {
            actions = dashboard.show(ui, |ui| {
                let rect = ui.available_rect_before_wrap();
                view_px = (
                    ((rect.width() * ppp).round() as u32).max(1),
                    ((rect.height() * ppp).round() as u32).max(1),
                );
                if let Some(((w, h), id)) = mirror {
                    // The eye's picture, whole, centred at its own aspect ratio.
                    let scale = (rect.width() / w as f32).min(rect.height() / h as f32);
                    let fit = egui::Rect::from_center_size(
                        rect.center(),
                        egui::vec2(w as f32 * scale, h as f32 * scale),
                    );
                    ui.put(
                        fit,
                        egui::Image::new(egui::load::SizedTexture::new(id, fit.size())),
                    );
                } else if let (Some((id, (w, h))), Some(_)) = (shown_picture, scene_id) {
                    // The fluoroscope's monitor, whole and centred; the mouse still drives
                    // the instruments over it as over the 3D view.
                    let scale = (rect.width() / w).min(rect.height() / h);
                    let fit = egui::Rect::from_center_size(rect.center(), egui::vec2(w, h) * scale);
                    ui.painter().rect_filled(rect, 0.0, egui::Color32::BLACK);
                    ui.put(
                        fit,
                        egui::Image::new(egui::load::SizedTexture::new(id, fit.size())),
                    );
                    let r = ui.interact(
                        rect,
                        egui::Id::unique("procedure picture"),
                        egui::Sense::click_and_drag(),
                    );
                    pointer = read_pointer(ui, &r, rect);
                } else if let Some(id) = scene_id {
                    let r = ui.put(
                        rect,
                        egui::Image::new(egui::load::SizedTexture::new(id, rect.size()))
                            .sense(egui::Sense::click_and_drag()),
                    );
                    pointer = read_pointer(ui, &r, rect);
                }
            });
            if let Some(t) = trainer {
                screen = trainee_screen(ui, t, dashboard);
            }
        });
        let ui_ms = ui_start.elapsed().as_secs_f32() * 1e3;
        self.act(actions);
        self.on_screens(el, screen);
        let Some(v) = self.view.as_mut() else {
            return Ok(());
        };
        v.egui
            .handle_platform_output(&v.window, out.platform_output.clone());
        // The 3D view, at the central panel's size.
        let render_start = Instant::now();
        ensure_scene(v, view_px);
        // Mirroring, the headset's renderer did the frame's work: its counters.
        let mut counters = match (&self.xr, mirror.is_some()) {
            (Some(x), true) => x.counters.clone(),
            _ => Default::default(),
        };
        if let Some(scene) = v.scene.as_ref().filter(|_| mirror.is_none()) {
            let aspect = scene.size.0 as f32 / scene.size.1 as f32;
            let eye = self.camera.view(aspect);
            if let Some((hands, shared)) = self.desktop.as_mut() {
                hands.pointer(&eye, pointer);
                shared.store(Arc::new(hands.published()));
            }
            // Under the procedure's own picture no part of the 3D view shows: not drawn.
            counters = if shown_picture.is_none() {
                self.scene_renders += 1;
                v.renderer
                    .render(RenderTarget::Single(&scene.view), scene.size, &[eye, eye])
            } else {
                v.renderer.idle_counters()
            };
        }
        let render_ms = render_start.elapsed().as_secs_f32() * 1e3;
        // The panels over the swapchain image.
        let jobs = v
            .egui
            .egui_ctx()
            .tessellate(out.shapes.clone(), out.pixels_per_point);
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [v.config.width, v.config.height],
            pixels_per_point: out.pixels_per_point,
        };
        for (id, deltas) in &out.textures_delta.set {
            for delta in deltas {
                v.painter
                    .update_texture(&v.gpu.device, &v.gpu.queue, *id, delta);
            }
        }
        match v.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(frame)
            | wgpu::CurrentSurfaceTexture::Suboptimal(frame) => {
                let target = frame
                    .texture
                    .create_view(&wgpu::TextureViewDescriptor::default());
                paint(v, &jobs, &screen, &target);
                v.gpu.queue.present(frame);
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                v.surface.configure(&v.gpu.device, &v.config);
            }
            other => return Err(WindowError::Swapchain(format!("{other:?}"))),
        }
        // The screenshot: the same frame, painted again into a texture that is read back.
        let due = match (self.opts.screenshot_at_s, &self.outcome) {
            // A desktop trainee's session ends at that time first (below), and the shot, the
            // frame after, shows its results.
            (Some(_), None) if self.trainer.is_some() => false,
            // egui lays a new screen out unseen on its first frame: a few frames on, it shows.
            (Some(_), Some(_)) if self.trainer.is_some_and(|t| t.shown < 3) => false,
            (Some(at), _) => self.dashboard.status.time_s >= at,
            (None, Some(_)) => true,
            (None, None) => false,
        };
        if !self.shot_taken
            && due
            && let Some(path) = self.opts.screenshot.clone()
        {
            let size = screenshot(v, &jobs, &screen, &path)?;
            self.shot = Some((size, path));
            self.shot_taken = true;
        }
        for id in &out.textures_delta.free {
            v.painter.free_texture(id);
        }
        v.gpu.check()?;
        self.frames += 1;
        let frame_ms = t0.elapsed().as_secs_f32() * 1e3;
        self.dashboard.frame(
            counters,
            FrameTimes {
                time_s: self.start.elapsed().as_secs_f64(),
                frame_ms,
                render_ms,
                ui_ms,
            },
        );
        if let Some(t) = self.trainer.as_mut().filter(|t| t.results) {
            t.shown += 1;
        }
        if let (Some(t), Some(at), None) = (
            self.trainer.as_mut(),
            self.opts.screenshot_at_s,
            &self.outcome,
        ) && self.dashboard.status.time_s >= at
        {
            t.results = true;
            self.end_session()?;
        }
        // A scripted run with a screenshot closes itself once the session is over.
        if self.outcome.is_some() && self.opts.screenshot.is_some() && self.shot_taken {
            el.exit();
        }
        Ok(())
    }
}

/// The mouse over the 3D view: where (normalised, y up), its buttons, the wheel's notches.
/// A grey picture as egui's image.
fn grey_image(p: &crate::imaging::fluoro::Picture) -> egui::ColorImage {
    egui::ColorImage::from_gray([p.width, p.height], &p.grey)
}

fn read_pointer(ui: &egui::Ui, r: &egui::Response, rect: egui::Rect) -> Pointer {
    let ndc = r.hover_pos().map(|p| {
        Vec2::new(
            (p.x - rect.left()) / rect.width() * 2.0 - 1.0,
            1.0 - (p.y - rect.top()) / rect.height() * 2.0,
        )
    });
    ui.input(|i| {
        let wheel = i
            .events
            .iter()
            .filter_map(|e| match e {
                egui::Event::MouseWheel { unit, delta, .. } => Some(match unit {
                    egui::MouseWheelUnit::Line | egui::MouseWheelUnit::Page => delta.y,
                    // A notch is about 50 points on pixel-scrolling devices.
                    egui::MouseWheelUnit::Point => delta.y / 50.0,
                }),
                _ => None,
            })
            .sum();
        Pointer {
            ndc,
            // A click whose press and release both fall between two frames (a quick click
            // while lavapipe renders one frame) still counts as down for this frame.
            primary_down: ndc.is_some()
                && (i.pointer.primary_down() || i.pointer.primary_pressed()),
            secondary_down: ndc.is_some()
                && (i.pointer.secondary_down() || i.pointer.secondary_pressed()),
            wheel: if ndc.is_some() { wheel } else { 0.0 },
        }
    })
}

/// (Re)makes the 3D view's texture when the central panel changes size.
fn ensure_scene(v: &mut View, size: (u32, u32)) {
    if v.scene.as_ref().is_some_and(|s| s.size == size) {
        return;
    }
    let texture = tracked_texture(
        &v.gpu.device,
        &v.gpu.ledger,
        "3d view",
        size,
        1,
        EYE_FORMAT,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
    );
    let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
    let id = match v.scene.take() {
        Some(old) => {
            v.painter.update_egui_texture_from_wgpu_texture(
                &v.gpu.device,
                &view,
                wgpu::FilterMode::Linear,
                old.id,
            );
            old.id
        }
        None => v
            .painter
            .register_native_texture(&v.gpu.device, &view, wgpu::FilterMode::Linear),
    };
    v.scene = Some(Scene {
        size,
        _texture: texture,
        view,
        id,
    });
}

/// Paints egui's primitives into `target` (cleared first).
fn paint(
    v: &mut View,
    jobs: &[egui::ClippedPrimitive],
    screen: &egui_wgpu::ScreenDescriptor,
    target: &wgpu::TextureView,
) {
    let mut encoder = v
        .gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("panels"),
        });
    let extra = v
        .painter
        .update_buffers(&v.gpu.device, &v.gpu.queue, &mut encoder, jobs, screen);
    {
        let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("panels"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        let mut pass = pass.forget_lifetime();
        v.painter.render(&mut pass, jobs, screen);
    }
    v.gpu
        .queue
        .submit(extra.into_iter().chain([encoder.finish()]));
}

/// Paints the frame into a readable texture and writes it as a PNG; returns its size.
fn screenshot(
    v: &mut View,
    jobs: &[egui::ClippedPrimitive],
    screen: &egui_wgpu::ScreenDescriptor,
    path: &std::path::Path,
) -> Result<(u32, u32), WindowError> {
    let size = (screen.size_in_pixels[0], screen.size_in_pixels[1]);
    let format = v.config.format;
    let texture = colour_texture(
        &v.gpu.device,
        "screenshot",
        size,
        1,
        format,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    );
    let target = texture.create_view(&wgpu::TextureViewDescriptor::default());
    paint(v, jobs, screen, &target);
    let mut pixels = crate::render::gpu::read_texture(&v.gpu, &texture, size, 1)?
        .pop()
        .unwrap_or_default();
    if matches!(
        format,
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
    ) {
        for p in pixels.chunks_exact_mut(4) {
            p.swap(0, 2);
        }
    }
    for p in pixels.chunks_exact_mut(4) {
        p[3] = 255;
    }
    crate::render::gpu::write_png(path, size, &pixels)?;
    Ok(size)
}

/// The desktop trainee's screen over the view: the start screen until Start, the pause
/// screen while paused, the results once the session has ended.
fn trainee_screen(
    ui: &mut egui::Ui,
    t: super::Trainer,
    d: &super::super::dashboard::Dashboard,
) -> super::super::screens::ScreenActions {
    use super::super::screens;
    match (&d.summary, t) {
        (Some(s), super::Trainer { results: true, .. }) => {
            screens::results(ui, s, d.status.steps_done.len(), d.info.steps.len())
        }
        (_, super::Trainer { started: false, .. }) => screens::start(ui, d.info),
        (_, super::Trainer { paused: true, .. }) => screens::paused(ui),
        _ => Default::default(),
    }
}
