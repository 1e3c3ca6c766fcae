//! A live panel (bevy_egui) to tune the hair and watch it: statistics with a plot of the step time, pause
//! and single step, the groom of the heads (strand count, edges, style), [`HairSettings`] (integrator,
//! damping), the wind ([`HairWind`]), the default material in human units, collisions (margin, collider
//! wireframes), and how hair is drawn: rendered ([`HairAppearance`]) or as gizmo lines. Behind the `egui`
//! feature.

use std::collections::VecDeque;

use bevy::gizmos::config::GizmoConfigStore;
use bevy::prelude::*;
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};

use super::HairGizmos;
use crate::detail::{HairCpuBudget, HairDetailLevel, HairDetailSettings, MAX_STEP_INTERVAL};
use crate::groom::{Combing, HairGroom, HairStyle};
use crate::render::{HairAppearance, HairMesh};
use crate::rod::{Integrator, RodMaterial};
use crate::simulation::{HairHead, HairPause, HairSettings, HairStatistics, HairVolume, SimulatedStrand};
use crate::wind::HairWind;

/// Adds a "Hair" window that reads [`HairStatistics`] and writes [`HairSettings`], [`HairPause`], [`HairWind`], every
/// head's [`HairGroom`] and the [`HairGizmos`] colours and collider drawing. Adds `EguiPlugin` when the
/// app has none. Needs a window and a camera (it draws in bevy_egui's primary context).
#[derive(Debug, Clone, Copy, Default)]
pub struct HairPanelPlugin;

impl Plugin for HairPanelPlugin {
    fn build(&self, app: &mut App) {
        if !app.is_plugin_added::<EguiPlugin>() {
            app.add_plugins(EguiPlugin::default());
        }
        app.add_systems(EguiPrimaryContextPass, hair_panel);
    }
}

/// What the panel remembers between frames.
#[derive(Default)]
struct PanelMemory {
    /// Step times of the last [`PanelMemory::PLOTTED_STEPS`] steps, ms.
    step_milliseconds: VecDeque<f32>,
    /// The step count when the last step time was recorded.
    recorded_step: u64,
    /// Smoothed frame rate, 1/s.
    frame_rate: f32,
    /// A groom edit whose slider is still held: applied (the hair regrown) when it is let go.
    held_groom: Option<GroomEdit>,
}

impl PanelMemory {
    const PLOTTED_STEPS: usize = 300;

    fn record(&mut self, statistics: &HairStatistics, frame_seconds: f32) {
        if statistics.steps != self.recorded_step {
            self.recorded_step = statistics.steps;
            if self.step_milliseconds.len() == Self::PLOTTED_STEPS {
                self.step_milliseconds.pop_front();
            }
            self.step_milliseconds.push_back(1e3 * statistics.step_seconds as f32);
        }
        if frame_seconds > 0.0 {
            let rate = 1.0 / frame_seconds;
            self.frame_rate =
                if self.frame_rate > 0.0 { self.frame_rate + 0.05 * (rate - self.frame_rate) } else { rate };
        }
    }
}

/// The parts of a [`HairGroom`] the panel edits.
#[derive(Debug, Clone, Copy, PartialEq)]
struct GroomEdit {
    strand_count: usize,
    segments: usize,
    style: HairStyle,
    combed: bool,
    gravity_preload: f32,
    followers_per_guide: usize,
    follower_clumping: f32,
    follower_clumping_variation: f32,
    /// The followers' scatter, mm.
    follower_scatter_mm: f32,
    /// The hairline's fade, mm.
    hairline_fade_mm: f32,
}

impl From<&HairGroom> for GroomEdit {
    fn from(groom: &HairGroom) -> Self {
        Self {
            strand_count: groom.strand_count,
            segments: groom.segments,
            style: groom.style,
            combed: groom.combing.is_some(),
            gravity_preload: groom.gravity_preload,
            followers_per_guide: groom.followers_per_guide,
            follower_clumping: groom.follower_clumping,
            follower_clumping_variation: groom.follower_clumping_variation,
            follower_scatter_mm: 1e3 * groom.follower_scatter,
            hairline_fade_mm: 1e3 * groom.hairline_fade,
        }
    }
}

impl GroomEdit {
    /// Writes the edited parts into `groom` (a combing switched on gets the default combing).
    fn apply(&self, groom: &mut HairGroom) {
        (groom.strand_count, groom.segments, groom.style) = (self.strand_count, self.segments, self.style);
        groom.gravity_preload = self.gravity_preload;
        groom.followers_per_guide = self.followers_per_guide;
        groom.follower_clumping = self.follower_clumping;
        groom.follower_clumping_variation = self.follower_clumping_variation;
        groom.follower_scatter = 1e-3 * self.follower_scatter_mm;
        groom.hairline_fade = 1e-3 * self.hairline_fade_mm;
        if self.combed != groom.combing.is_some() {
            groom.combing = self.combed.then(Combing::default);
        }
    }
}

/// Draws the panel and applies what was changed in it.
#[allow(clippy::too_many_arguments)]
fn hair_panel(
    mut contexts: EguiContexts,
    real_time: Res<Time<Real>>,
    mut settings: ResMut<HairSettings>,
    mut pause: ResMut<HairPause>,
    mut wind: ResMut<HairWind>,
    statistics: Res<HairStatistics>,
    gizmo_store: Option<ResMut<GizmoConfigStore>>,
    mut strands: Query<&mut SimulatedStrand>,
    mut grooms: Query<&mut HairGroom>,
    mut memory: Local<PanelMemory>,
    mut commands: Commands,
    heads: Query<(Entity, Option<&HairAppearance>), With<HairHead>>,
    mut hair_meshes: Query<&mut Visibility, With<HairMesh>>,
    detail: Option<(ResMut<HairDetailSettings>, ResMut<HairCpuBudget>)>,
    #[cfg(feature = "gpu")] gpu: Option<Res<crate::render::HairGpuStatus>>,
) -> Result {
    memory.record(&statistics, real_time.delta_secs());
    let mut edited = settings.clone();
    let mut edited_pause = pause.clone();
    let mut edited_wind = wind.clone();
    let mut reset = false;
    let mut groom = memory.held_groom.or_else(|| grooms.iter().next().map(GroomEdit::from));
    let mut groom_held = false;
    let mut drawing = gizmo_store.as_ref().map(|store| store.config::<HairGizmos>().1.clone());
    let shown_drawing = drawing.clone();
    let rendered_shown = hair_meshes.iter().any(|visibility| *visibility != Visibility::Hidden);
    let mut rendered = rendered_shown;
    let shown_appearance = heads.iter().next().map(|(_, appearance)| appearance.cloned().unwrap_or_default());
    let mut appearance = shown_appearance.clone();
    let mut edited_detail = detail.as_ref().map(|(settings, budget)| ((**settings).clone(), **budget));
    egui::Window::new("Hair").default_width(320.0).show(contexts.ctx_mut()?, |ui| {
        statistics_grid(ui, &statistics, memory.frame_rate);
        #[cfg(feature = "gpu")]
        if let Some(gpu) = gpu.as_deref() {
            gpu_grid(ui, gpu);
        }
        step_time_plot(ui, &memory.step_milliseconds);
        ui.horizontal(|ui| {
            let label = if edited_pause.paused { "▶ run" } else { "⏸ pause" };
            if ui.button(label).clicked() {
                edited_pause.paused = !edited_pause.paused;
            }
            if ui.add_enabled(edited_pause.paused, egui::Button::new("single step")).clicked() {
                edited_pause.step_once();
            }
            reset = ui.button("reset to rest").clicked();
        });
        if let Some(groom) = groom.as_mut() {
            ui.separator();
            groom_held = groom_grid(ui, groom);
        }
        ui.collapsing("simulation", |ui| settings_grid(ui, &mut edited));
        ui.collapsing("hair–hair (volume)", |ui| volume_grid(ui, &mut edited.volume));
        ui.collapsing("wind", |ui| wind_grid(ui, &mut edited_wind));
        ui.collapsing("material", |ui| material_grid(ui, &mut edited.default_material));
        ui.collapsing("collisions", |ui| collision_grid(ui, &mut edited, drawing.as_mut()));
        if let Some((detail, budget)) = edited_detail.as_mut() {
            ui.collapsing("levels of detail and budget", |ui| detail_grid(ui, detail, budget, &statistics));
        }
        ui.collapsing("drawing", |ui| {
            ui.horizontal(|ui| {
                ui.checkbox(&mut rendered, "rendered hair");
                if let Some(drawing) = drawing.as_mut() {
                    ui.checkbox(&mut drawing.draw_strands, "gizmo lines");
                }
            });
            if let Some(appearance) = appearance.as_mut() {
                appearance_grid(ui, appearance);
            }
            if let Some(drawing) = drawing.as_mut() {
                ui.label("gizmo line colours");
                color_grid(ui, drawing);
            }
        });
    });
    if rendered != rendered_shown {
        let shown = if rendered { Visibility::Inherited } else { Visibility::Hidden };
        hair_meshes.iter_mut().for_each(|mut visibility| *visibility = shown);
    }
    if let Some(appearance) = appearance.filter(|appearance| Some(appearance) != shown_appearance.as_ref()) {
        for (head, _) in &heads {
            commands.entity(head).insert(appearance.clone());
        }
    }
    if edited != *settings {
        *settings = edited;
    }
    if edited_pause != *pause {
        *pause = edited_pause;
    }
    if edited_wind != *wind {
        *wind = edited_wind;
    }
    if let (Some((mut detail, mut budget)), Some((edited, edited_budget))) = (detail, edited_detail) {
        if *detail != edited {
            *detail = edited;
        }
        if *budget != edited_budget {
            *budget = edited_budget;
        }
    }
    memory.held_groom = groom.filter(|_| groom_held);
    if let Some(edit) = groom.filter(|_| !groom_held) {
        for mut groom in &mut grooms {
            if GroomEdit::from(&*groom) != edit {
                edit.apply(&mut groom);
            }
        }
    }
    if let (Some(mut store), Some(drawing)) =
        (gizmo_store, drawing.filter(|drawing| Some(drawing) != shown_drawing.as_ref()))
    {
        *store.config_mut::<HairGizmos>().1 = drawing;
    }
    if reset {
        strands.iter_mut().for_each(|mut strand| strand.reset_to_rest());
    }
    Ok(())
}

fn statistics_grid(ui: &mut egui::Ui, statistics: &HairStatistics, frame_rate: f32) {
    egui::Grid::new("hair statistics").num_columns(2).show(ui, |ui| {
        let mut row = |name: &str, value: String| {
            ui.label(name);
            ui.label(value);
            ui.end_row();
        };
        let elsewhere = match statistics.strands_elsewhere {
            0 => String::new(),
            strands => format!(" (+ {strands} on the GPU)"),
        };
        row("strands / nodes", format!("{} / {}{elsewhere}", statistics.strands, statistics.nodes));
        row("followers", format!("{} ({:.2} ms)", statistics.followers, 1e3 * statistics.follower_seconds));
        row(
            "hair–hair grid",
            format!("{:.2} ms, densest {:.2}", 1e3 * statistics.volume_seconds, statistics.max_volume_fraction),
        );
        row("step time", format!("{:.2} ms", 1e3 * statistics.step_seconds));
        let interval = match statistics.budget_step_interval {
            0 | 1 => String::new(),
            interval => format!(", stepped every {interval} fixed steps to keep the budget"),
        };
        row("hair update (CPU)", format!("{:.2} ms{interval}", 1e3 * statistics.update_seconds));
        row("frame rate", format!("{frame_rate:.0} fps"));
        row("largest strain", format!("{:.1e}", statistics.max_strain));
        row("Newton iterations", format!("{:.2} per strand", statistics.mean_newton_iterations));
        row("nodes in contact", statistics.contacts.to_string());
        row("steps / skipped", format!("{} / {}", statistics.steps, statistics.skipped_steps));
        row("faults / quarantined", format!("{} / {}", statistics.faults, statistics.quarantined));
    });
    if let Some(error) = &statistics.settings_error {
        ui.colored_label(egui::Color32::LIGHT_RED, error);
    }
}

/// What the GPU's step did, where `HairGpuPlugin` runs: the strands it steps, what the last read-back said
/// about them, and what stepping them cost the render thread (on a software adapter, the GPU's work too).
#[cfg(feature = "gpu")]
fn gpu_grid(ui: &mut egui::Ui, gpu: &crate::render::HairGpuStatus) {
    if let Some(error) = &gpu.error {
        ui.colored_label(egui::Color32::LIGHT_RED, format!("GPU step: {error}"));
    }
    if gpu.strands == 0 {
        return;
    }
    egui::Grid::new("hair GPU statistics").num_columns(2).show(ui, |ui| {
        let mut row = |name: &str, value: String| {
            ui.label(name);
            ui.label(value);
            ui.end_row();
        };
        row("GPU step", format!("{} strands, {} steps", gpu.strands, gpu.steps));
        row(
            "GPU render thread",
            format!("{:.2} ms (driver {:.2} ms)", 1e3 * gpu.render_thread_seconds, 1e3 * gpu.render_driver_seconds),
        );
        if let Some(timings) = gpu.timings {
            let time = format!("{:.2} ms (grid {:.2} ms)", 1e3 * timings.step_seconds, 1e3 * timings.grid_seconds);
            row("GPU time a step", time);
        }
        row("GPU Newton iterations", format!("{:.2} per strand", gpu.mean_newton_iterations));
        row("GPU largest strain", format!("{:.1e}", gpu.max_strain));
        row("GPU nodes in contact", gpu.contacts.to_string());
        row("GPU hair–hair grid", format!("densest {:.2}", gpu.max_volume_fraction));
        row("GPU faults / given up", format!("{} / {}", gpu.faults, gpu.contact_given_up));
    });
}

/// A line plot of the recent step times, scaled to their largest.
fn step_time_plot(ui: &mut egui::Ui, step_milliseconds: &VecDeque<f32>) {
    let largest = step_milliseconds.iter().copied().fold(0.0_f32, f32::max);
    ui.label(format!("step time, last {} steps (top: {largest:.1} ms)", step_milliseconds.len()));
    let (response, painter) = ui.allocate_painter(egui::vec2(ui.available_width(), 48.0), egui::Sense::hover());
    let area = response.rect;
    painter.rect_filled(area, 2.0, ui.visuals().extreme_bg_color);
    if largest <= 0.0 {
        return;
    }
    let step_width = area.width() / (PanelMemory::PLOTTED_STEPS - 1) as f32;
    let points = step_milliseconds
        .iter()
        .enumerate()
        .map(|(index, &milliseconds)| {
            egui::pos2(area.left() + step_width * index as f32, area.bottom() - area.height() * milliseconds / largest)
        })
        .collect();
    painter.line(points, egui::Stroke::new(1.5, egui::Color32::LIGHT_GREEN));
}

/// The groom's controls; returns whether a slider is being dragged (the hair is regrown when it is let go).
fn groom_grid(ui: &mut egui::Ui, groom: &mut GroomEdit) -> bool {
    let mut held = false;
    egui::Grid::new("hair groom").num_columns(2).show(ui, |ui| {
        held |=
            grid_row(ui, "strands", egui::Slider::new(&mut groom.strand_count, 0..=8000).logarithmic(true)).dragged();
        held |= grid_row(ui, "edges per strand", egui::Slider::new(&mut groom.segments, 2..=64)).dragged();
        held |=
            grid_row(ui, "followers per strand", egui::Slider::new(&mut groom.followers_per_guide, 0..=30)).dragged();
        held |= grid_row(ui, "follower clumping", egui::Slider::new(&mut groom.follower_clumping, 0.0..=1.0)).dragged();
        held |= grid_row(ui, "  its variation", egui::Slider::new(&mut groom.follower_clumping_variation, 0.0..=1.0))
            .dragged();
        held |= grid_row(ui, "follower scatter (mm)", egui::Slider::new(&mut groom.follower_scatter_mm, 0.0..=20.0))
            .dragged();
        ui.label("style");
        ui.horizontal_wrapped(|ui| {
            for style in HairStyle::ALL {
                ui.selectable_value(&mut groom.style, style, style.name());
            }
        });
        ui.end_row();
        ui.label("combed");
        ui.checkbox(&mut groom.combed, "along the scalp, from a parting");
        ui.end_row();
        held |= grid_row(ui, "gravity preload", egui::Slider::new(&mut groom.gravity_preload, 0.0..=1.0)).dragged();
        held |=
            grid_row(ui, "hairline fade (mm)", egui::Slider::new(&mut groom.hairline_fade_mm, 0.0..=20.0)).dragged();
    });
    held
}

fn settings_grid(ui: &mut egui::Ui, settings: &mut HairSettings) {
    egui::Grid::new("hair settings").num_columns(2).show(ui, |ui| {
        ui.label("gravity (m/s²)");
        ui.horizontal(|ui| {
            for component in [&mut settings.gravity.x, &mut settings.gravity.y, &mut settings.gravity.z] {
                ui.add(egui::DragValue::new(component).speed(0.1).range(-50.0..=50.0));
            }
        });
        ui.end_row();
        ui.label("integrator");
        ui.horizontal(|ui| {
            ui.radio_value(&mut settings.integrator, Integrator::Bdf2, "BDF2");
            ui.radio_value(&mut settings.integrator, Integrator::BackwardEuler, "backward Euler");
        });
        ui.end_row();
        grid_row(ui, "air damping (1/s)", egui::Slider::new(&mut settings.air_damping, 0.0..=30.0));
        grid_row(ui, "drag along / across", egui::Slider::new(&mut settings.axial_drag_ratio, 0.0..=1.0));
        let internal_damping = egui::Slider::new(&mut settings.internal_damping, 0.0..=0.05).logarithmic(true);
        grid_row(ui, "internal damping (s)", internal_damping);
        grid_row(ui, "Newton iterations (max)", egui::Slider::new(&mut settings.max_newton_iterations, 1..=8));
        grid_row(ui, "steps per frame (max)", egui::Slider::new(&mut settings.max_steps_per_frame, 0..=8));
        let teleport_distance = egui::Slider::new(&mut settings.teleport_distance, 0.05..=5.0).logarithmic(true);
        grid_row(ui, "teleport distance (m)", teleport_distance);
        grid_row(ui, "style hold (1/s)", egui::Slider::new(&mut settings.style_hold.rate, 0.0..=100.0));
        grid_row(ui, "style hold reach", egui::Slider::new(&mut settings.style_hold.reach, 0.0..=1.0));
    });
}

/// Levels of detail ([`HairDetailSettings`]), the CPU budget ([`HairCpuBudget`]) and the heads at each level.
fn detail_grid(
    ui: &mut egui::Ui,
    detail: &mut HairDetailSettings,
    budget: &mut HairCpuBudget,
    statistics: &HairStatistics,
) {
    let heads = statistics.heads_by_detail;
    egui::Grid::new("hair detail").num_columns(2).show(ui, |ui| {
        ui.label("CPU budget");
        let mut budgeted = budget.milliseconds.is_some();
        if ui.checkbox(&mut budgeted, "on").changed() {
            budget.milliseconds = budgeted.then_some(4.0);
        }
        ui.end_row();
        if let Some(milliseconds) = budget.milliseconds.as_mut() {
            grid_row(ui, "budget (ms per step)", egui::Slider::new(milliseconds, 0.5..=30.0).logarithmic(true));
            let coarsest = egui::Slider::new(&mut budget.max_step_interval, 1..=MAX_STEP_INTERVAL);
            grid_row(ui, "coarsest step interval", coarsest);
        }
        ui.label("chosen from the camera");
        ui.checkbox(&mut detail.enabled, "on");
        ui.end_row();
        let full = egui::Slider::new(&mut detail.full_detail_distance, 0.5..=50.0).logarithmic(true);
        grid_row(ui, "full detail within (m)", full);
        grid_row(ui, "longest step interval", egui::Slider::new(&mut detail.max_step_interval, 1..=MAX_STEP_INTERVAL));
        let carried = egui::Slider::new(&mut detail.carried_distance, 1.0..=1000.0).logarithmic(true);
        grid_row(ui, "carried beyond (m)", carried);
        ui.label("out of sight");
        let mut carried_off_screen = detail.off_screen == HairDetailLevel::Carried;
        if ui.checkbox(&mut carried_off_screen, "carried").changed() {
            detail.off_screen = if carried_off_screen {
                HairDetailLevel::Carried
            } else {
                HairDetailLevel::Stepped(detail.max_step_interval)
            };
        }
        ui.end_row();
        ui.label("heads full / ½ / ≤¼ / carried");
        ui.label(format!("{} / {} / {} / {}", heads.full, heads.every_second_step, heads.rarer, heads.carried));
        ui.end_row();
        ui.label("strands stepped / resting");
        ui.label(format!("{} / {}", statistics.strands, statistics.unstepped_strands));
        ui.end_row();
    });
}

/// Hair–hair interaction through the grid ([`crate::volume::HairVolume`]).
fn volume_grid(ui: &mut egui::Ui, volume: &mut HairVolume) {
    egui::Grid::new("hair volume").num_columns(2).show(ui, |ui| {
        ui.label("grid");
        ui.checkbox(&mut volume.enabled, "hair meets hair");
        ui.end_row();
        grid_row(ui, "cell size (m)", egui::Slider::new(&mut volume.cell_size, 0.002..=0.05).logarithmic(true));
        grid_row(ui, "velocity smoothing (1/s)", egui::Slider::new(&mut volume.velocity_smoothing, 0.0..=50.0));
        let target = egui::Slider::new(&mut volume.target_volume_fraction, 0.01..=0.5).logarithmic(true);
        grid_row(ui, "target volume fraction", target);
        grid_row(ui, "pressure stiffness (Pa)", egui::Slider::new(&mut volume.stiffness, 0.0..=200.0));
        ui.label("");
        ui.checkbox(&mut volume.keep_groomed_volume, "groomed packing at rest");
        ui.end_row();
    });
}

/// The wind: speed and direction (from where it blows, as an angle about the vertical), gusts and
/// turbulence.
fn wind_grid(ui: &mut egui::Ui, wind: &mut HairWind) {
    let horizontal = Vec2::new(wind.velocity.x, wind.velocity.z);
    let mut speed = wind.velocity.length();
    // The angle the wind blows towards, in degrees from +X towards +Z.
    let mut heading = if horizontal == Vec2::ZERO { 0.0 } else { horizontal.y.atan2(horizontal.x).to_degrees() };
    let (shown_speed, shown_heading) = (speed, heading);
    egui::Grid::new("hair wind").num_columns(2).show(ui, |ui| {
        grid_row(ui, "speed (m/s)", egui::Slider::new(&mut speed, 0.0..=15.0));
        grid_row(ui, "blowing towards (°)", egui::Slider::new(&mut heading, -180.0..=180.0));
        grid_row(ui, "gusts (± m/s)", egui::Slider::new(&mut wind.gusts, 0.0..=10.0));
        grid_row(ui, "gust period (s)", egui::Slider::new(&mut wind.gust_period, 0.2..=10.0).logarithmic(true));
        grid_row(ui, "turbulence (m/s)", egui::Slider::new(&mut wind.turbulence, 0.0..=5.0));
        grid_row(ui, "eddy size (m)", egui::Slider::new(&mut wind.turbulence_scale, 0.05..=2.0).logarithmic(true));
    });
    // Written only when a slider moved, so that a wind with an up or down part (set in code) is kept
    // until the panel changes it.
    if speed != shown_speed || heading != shown_heading {
        wind.velocity = speed * Vec3::new(heading.to_radians().cos(), 0.0, heading.to_radians().sin());
    }
}

fn material_grid(ui: &mut egui::Ui, material: &mut RodMaterial) {
    let mut radius_micrometres = 0.5e6 * (material.semi_axis_1 + material.semi_axis_2);
    let mut youngs_gigapascals = 1e-9 * material.youngs_modulus;
    let poisson_ratio = material.youngs_modulus / (2.0 * material.shear_modulus) - 1.0;
    egui::Grid::new("hair material").num_columns(2).show(ui, |ui| {
        grid_row(ui, "fibre radius (µm)", egui::Slider::new(&mut radius_micrometres, 10.0..=500.0).logarithmic(true));
        grid_row(
            ui,
            "Young's modulus (GPa)",
            egui::Slider::new(&mut youngs_gigapascals, 0.01..=10.0).logarithmic(true),
        );
        grid_row(ui, "density (kg/m³)", egui::Slider::new(&mut material.density, 100.0..=3000.0));
    });
    let radius = 1e-6 * radius_micrometres;
    if (radius - 0.5 * (material.semi_axis_1 + material.semi_axis_2)).abs() > 1e-12 {
        (material.semi_axis_1, material.semi_axis_2) = (radius, radius);
    }
    if (1e9 * youngs_gigapascals - material.youngs_modulus).abs() > 1.0 {
        *material = RodMaterial::round(radius, 1e9 * youngs_gigapascals, poisson_ratio, material.density);
    }
}

/// The collision margin, and whether colliders are drawn (when hair is drawn at all).
fn collision_grid(ui: &mut egui::Ui, settings: &mut HairSettings, drawing: Option<&mut HairGizmos>) {
    let mut margin_millimetres = 1e3 * settings.collision_margin;
    egui::Grid::new("hair collisions").num_columns(2).show(ui, |ui| {
        grid_row(ui, "collision margin (mm)", egui::Slider::new(&mut margin_millimetres, 0.0..=10.0));
    });
    if (1e-3 * margin_millimetres - settings.collision_margin).abs() > 1e-7 {
        settings.collision_margin = 1e-3 * margin_millimetres;
    }
    if let Some(drawing) = drawing {
        ui.checkbox(&mut drawing.draw_colliders, "draw colliders");
    }
}

/// One row of a two-column grid: a label and its widget, whose response is returned.
fn grid_row(ui: &mut egui::Ui, label: &str, widget: impl egui::Widget) -> egui::Response {
    ui.label(label);
    let response = ui.add(widget);
    ui.end_row();
    response
}

/// The rendered hair's look: colour presets by melanin, root and tip colours, highlights and thickness.
fn appearance_grid(ui: &mut egui::Ui, appearance: &mut HairAppearance) {
    ui.horizontal_wrapped(|ui| {
        for (name, preset) in HairAppearance::presets() {
            if ui.button(name).clicked() {
                (appearance.root_color, appearance.tip_color) = (preset.root_color, preset.tip_color);
            }
        }
    });
    ui.horizontal(|ui| {
        for (name, color) in [("root", &mut appearance.root_color), ("tip", &mut appearance.tip_color)] {
            ui.label(name);
            let mut rgb = color.to_srgba().to_f32_array_no_alpha();
            if ui.color_edit_button_rgb(&mut rgb).changed() {
                *color = Color::srgb_from_array(rgb);
            }
        }
    });
    let mut tilt_degrees = appearance.cuticle_tilt.to_degrees();
    let mut width_degrees = appearance.highlight_width.to_degrees();
    egui::Grid::new("hair appearance").num_columns(2).show(ui, |ui| {
        grid_row(ui, "brightness variation", egui::Slider::new(&mut appearance.color_variation, 0.0..=1.0));
        grid_row(ui, "highlight strength", egui::Slider::new(&mut appearance.specular, 0.0..=1.0));
        grid_row(ui, "highlight filtering", egui::Slider::new(&mut appearance.highlight_filtering, 0.0..=4.0));
        grid_row(ui, "cuticle tilt (°)", egui::Slider::new(&mut tilt_degrees, 0.0..=10.0));
        grid_row(ui, "highlight width (°)", egui::Slider::new(&mut width_degrees, 1.0..=30.0));
        grid_row(ui, "thickness (× real)", egui::Slider::new(&mut appearance.thickness_scale, 0.25..=8.0));
        grid_row(ui, "tip taper", egui::Slider::new(&mut appearance.tip_taper, 0.0..=1.0));
        grid_row(ui, "length variation", egui::Slider::new(&mut appearance.length_variation, 0.0..=1.0));
        grid_row(ui, "min width (px)", egui::Slider::new(&mut appearance.min_pixel_width, 0.0..=3.0));
        grid_row(ui, "root occlusion", egui::Slider::new(&mut appearance.root_occlusion, 0.0..=1.0));
        grid_row(
            ui,
            "light penetration (mm)",
            egui::Slider::from_get_set(0.0..=20.0, |value| {
                if let Some(mm) = value {
                    appearance.light_penetration = mm as f32 * 1e-3;
                }
                f64::from(appearance.light_penetration) * 1e3
            }),
        );
    });
    if (tilt_degrees - appearance.cuticle_tilt.to_degrees()).abs() > 1e-4 {
        appearance.cuticle_tilt = tilt_degrees.to_radians();
    }
    if (width_degrees - appearance.highlight_width.to_degrees()).abs() > 1e-4 {
        appearance.highlight_width = width_degrees.to_radians();
    }
}

/// Colour pickers for root and tip, and the presets of [`HairGizmos::presets`].
fn color_grid(ui: &mut egui::Ui, colors: &mut HairGizmos) {
    ui.horizontal(|ui| {
        for (name, color) in [("root", &mut colors.root_color), ("tip", &mut colors.tip_color)] {
            ui.label(name);
            let mut rgb = color.to_srgba().to_f32_array_no_alpha();
            if ui.color_edit_button_rgb(&mut rgb).changed() {
                *color = Color::srgb_from_array(rgb);
            }
        }
    });
    ui.horizontal_wrapped(|ui| {
        for (name, preset) in HairGizmos::presets() {
            if ui.button(name).clicked() {
                (colors.root_color, colors.tip_color) = (preset.root_color, preset.tip_color);
            }
        }
    });
}
