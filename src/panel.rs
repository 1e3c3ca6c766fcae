//! A live panel (bevy_egui) to tune [`HairSettings`] and the hair's colours and to watch
//! [`HairStatistics`]. Behind the `egui` feature.

use bevy::gizmos::config::GizmoConfigStore;
use bevy::prelude::*;
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};

use crate::gizmos::HairGizmos;
use crate::rod::RodMaterial;
use crate::settings::{HairSettings, HairStatistics};
use crate::strand::Strand;

/// Adds a "Hair" window: statistics, every [`HairSettings`] field with its unit, the default material,
/// the hair colours and a button that puts every strand back in its rest pose. Adds `EguiPlugin` when
/// the app has none. Needs a window and a camera (it draws in bevy_egui's primary context).
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

/// Draws the panel and applies what was changed in it.
fn hair_panel(
    mut contexts: EguiContexts,
    mut settings: ResMut<HairSettings>,
    statistics: Res<HairStatistics>,
    gizmo_store: Option<ResMut<GizmoConfigStore>>,
    mut strands: Query<&mut Strand>,
) -> Result {
    let mut edited = settings.clone();
    let mut reset = false;
    let mut colors = gizmo_store.as_ref().map(|store| {
        let (_, hair) = store.config::<HairGizmos>();
        (hair.root_color.to_srgba().to_f32_array_no_alpha(), hair.tip_color.to_srgba().to_f32_array_no_alpha())
    });
    let shown_colors = colors;
    egui::Window::new("Hair").default_width(300.0).show(contexts.ctx_mut()?, |ui| {
        statistics_grid(ui, &statistics);
        ui.separator();
        settings_grid(ui, &mut edited);
        ui.separator();
        material_grid(ui, &mut edited.default_material);
        if let Some((root, tip)) = colors.as_mut() {
            ui.separator();
            ui.horizontal(|ui| {
                ui.label("root colour");
                ui.color_edit_button_rgb(root);
                ui.label("tip colour");
                ui.color_edit_button_rgb(tip);
            });
        }
        ui.separator();
        reset = ui.button("Reset hair to its rest pose").clicked();
    });
    if edited != *settings {
        *settings = edited;
    }
    if let (Some(mut store), Some((root, tip))) = (gizmo_store, colors.filter(|_| colors != shown_colors)) {
        let (_, hair) = store.config_mut::<HairGizmos>();
        hair.root_color = Color::srgb_from_array(root);
        hair.tip_color = Color::srgb_from_array(tip);
    }
    if reset {
        strands.iter_mut().for_each(|mut strand| strand.reset_to_rest());
    }
    Ok(())
}

fn statistics_grid(ui: &mut egui::Ui, statistics: &HairStatistics) {
    egui::Grid::new("hair statistics").num_columns(2).show(ui, |ui| {
        let mut row = |name: &str, value: String| {
            ui.label(name);
            ui.label(value);
            ui.end_row();
        };
        row("strands", statistics.strands.to_string());
        row("step time", format!("{:.2} ms", 1e3 * statistics.step_seconds));
        row("Newton iterations", format!("{:.2} per strand", statistics.mean_newton_iterations));
        row("largest strain", format!("{:.1e}", statistics.max_strain));
        row("steps / skipped", format!("{} / {}", statistics.steps, statistics.skipped_steps));
        row("faults", statistics.faults.to_string());
    });
    if let Some(error) = &statistics.settings_error {
        ui.colored_label(egui::Color32::LIGHT_RED, error);
    }
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
        ui.label("air damping (1/s)");
        ui.add(egui::Slider::new(&mut settings.air_damping, 0.0..=30.0));
        ui.end_row();
        ui.label("internal damping (s)");
        ui.add(egui::Slider::new(&mut settings.internal_damping, 0.0..=0.05).logarithmic(true));
        ui.end_row();
        ui.label("Newton iterations (max)");
        ui.add(egui::Slider::new(&mut settings.max_newton_iterations, 1..=8));
        ui.end_row();
        ui.label("steps per frame (max)");
        ui.add(egui::Slider::new(&mut settings.max_steps_per_frame, 0..=8));
        ui.end_row();
        ui.label("teleport distance (m)");
        ui.add(egui::Slider::new(&mut settings.teleport_distance, 0.05..=5.0).logarithmic(true));
        ui.end_row();
    });
}

fn material_grid(ui: &mut egui::Ui, material: &mut RodMaterial) {
    let mut radius_micrometres = 0.5e6 * (material.semi_axis_1 + material.semi_axis_2);
    let mut youngs_gigapascals = 1e-9 * material.youngs_modulus;
    let poisson_ratio = material.youngs_modulus / (2.0 * material.shear_modulus) - 1.0;
    egui::Grid::new("hair material").num_columns(2).show(ui, |ui| {
        ui.label("fibre radius (µm)");
        ui.add(egui::Slider::new(&mut radius_micrometres, 10.0..=500.0).logarithmic(true));
        ui.end_row();
        ui.label("Young's modulus (GPa)");
        ui.add(egui::Slider::new(&mut youngs_gigapascals, 0.01..=10.0).logarithmic(true));
        ui.end_row();
        ui.label("density (kg/m³)");
        ui.add(egui::Slider::new(&mut material.density, 100.0..=3000.0));
        ui.end_row();
    });
    let radius = 1e-6 * radius_micrometres;
    if (radius - 0.5 * (material.semi_axis_1 + material.semi_axis_2)).abs() > 1e-12 {
        (material.semi_axis_1, material.semi_axis_2) = (radius, radius);
    }
    if (1e9 * youngs_gigapascals - material.youngs_modulus).abs() > 1.0 {
        *material = RodMaterial::round(radius, 1e9 * youngs_gigapascals, poisson_ratio, material.density);
    }
}
