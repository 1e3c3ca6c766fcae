//! The hair shader (`src/render/draw.wgsl`) composed with Bevy's own shader modules by naga_oil, the
//! composer Bevy's pipeline cache uses, and validated by naga, for each way Bevy compiles it: the main
//! pass with and without multisampling and in-shader tonemapping, and the shadow (prepass) pass with and
//! without depth-clamp emulation. Needs no GPU: a broken shader, or one that no longer fits Bevy's
//! bindings, fails here instead of at run time.
//!
//! Bevy's modules are read from the sources of the Bevy crates the `render` feature builds with (found with
//! `cargo metadata`, which downloads those a plain `cargo test` did not need, as it would for a build), so
//! the check follows the Bevy version in `Cargo.lock` and passes on a machine with an empty cargo cache.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use naga_oil::compose::{
    ComposableModuleDescriptor, Composer, NagaModuleDescriptor, ShaderDefValue, ShaderLanguage, ShaderType,
};

const HAIR_SHADER: &str = include_str!("../../src/render/draw.wgsl");

/// The host's target triple, as `rustc -vV` names it.
fn host_triple() -> String {
    let output = Command::new("rustc").arg("-vV").output().expect("rustc runs");
    let text = String::from_utf8(output.stdout).unwrap();
    text.lines().find_map(|line| line.strip_prefix("host: ")).expect("rustc -vV names the host").to_string()
}

/// Source directories of the Bevy crates of this crate's build with the renderer (`render` feature), for the
/// host only (those of other platforms are never needed).
fn bevy_source_directories() -> Vec<PathBuf> {
    let output = Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--features", "render", "--filter-platform", &host_triple()])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(output.status.success(), "cargo metadata: {}", String::from_utf8_lossy(&output.stderr));
    let json = String::from_utf8(output.stdout).unwrap();
    // Every `"manifest_path":"…/bevy_xyz-0.19.1/Cargo.toml"`; no JSON parser needed for that.
    let key = "\"manifest_path\":\"";
    json.match_indices(key)
        .filter_map(|(at, _)| {
            let rest = &json[at + key.len()..];
            let path = Path::new(&rest[..rest.find('"')?]);
            let directory = path.parent()?;
            let name = directory.file_name()?.to_str()?;
            (name.starts_with("bevy_") && name.contains("0.19")).then(|| directory.join("src"))
        })
        .collect()
}

fn wgsl_files(directory: &Path, found: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(directory).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.is_dir() {
            wgsl_files(&path, found);
        } else if path.extension().is_some_and(|extension| extension == "wgsl") {
            found.push(path);
        }
    }
}

/// Shader definitions Bevy gives a module when it loads it (`load_shader_library!` settings).
fn module_defaults(source: &str) -> HashMap<String, ShaderDefValue> {
    let mut defaults = HashMap::new();
    if source.contains("#define_import_path bevy_pbr::mesh_view_types") {
        defaults.insert("MAX_DIRECTIONAL_LIGHTS".into(), ShaderDefValue::UInt(10));
        defaults.insert("MAX_CASCADES_PER_LIGHT".into(), ShaderDefValue::UInt(4));
        defaults.insert("MAX_RECT_LIGHTS".into(), ShaderDefValue::UInt(8));
    }
    defaults
}

/// A composer holding every importable module of Bevy's crates, added in dependency order.
fn bevy_composer() -> Composer {
    let mut files = Vec::new();
    for directory in bevy_source_directories() {
        wgsl_files(&directory, &mut files);
    }
    let mut pending: Vec<(PathBuf, String)> = files
        .into_iter()
        .filter_map(|path| Some((path.clone(), std::fs::read_to_string(&path).ok()?)))
        .filter(|(_, source)| source.contains("#define_import_path"))
        .collect();
    assert!(pending.len() > 50, "Bevy's shader modules were not found ({} files)", pending.len());
    let mut composer = Composer::default();
    // A module can only be added after the modules it imports: retry until nothing more can be added.
    loop {
        let before = pending.len();
        pending.retain(|(path, source)| {
            composer
                .add_composable_module(ComposableModuleDescriptor {
                    source,
                    file_path: &path.to_string_lossy(),
                    language: ShaderLanguage::Wgsl,
                    shader_defs: module_defaults(source),
                    ..Default::default()
                })
                .is_err()
        });
        if pending.len() == before {
            break;
        }
    }
    composer
}

/// The definitions Bevy's mesh pipeline gives every material shader on a device with storage buffers
/// (`PER_OBJECT_BUFFER_BATCH_SIZE`, which puts the meshes in a uniform array, is defined only without
/// them, on WebGL2).
fn common_definitions() -> HashMap<String, ShaderDefValue> {
    let mut definitions: HashMap<String, ShaderDefValue> = HashMap::new();
    definitions.insert("MATERIAL_BIND_GROUP".into(), ShaderDefValue::UInt(3));
    definitions.insert("AVAILABLE_STORAGE_BUFFER_BINDINGS".into(), ShaderDefValue::UInt(16));
    definitions.insert("VERTEX_OUTPUT_INSTANCE_INDEX".into(), ShaderDefValue::Bool(true));
    definitions.insert("VIEW_PROJECTION_PERSPECTIVE".into(), ShaderDefValue::Bool(true));
    definitions
}

fn compose(composer: &mut Composer, stage: ShaderType, definitions: &[(&str, ShaderDefValue)]) -> naga::Module {
    let mut shader_defs = common_definitions();
    shader_defs.extend(definitions.iter().map(|(name, value)| (name.to_string(), *value)));
    composer
        .make_naga_module(NagaModuleDescriptor {
            source: HAIR_SHADER,
            file_path: "src/render/draw.wgsl",
            shader_type: stage,
            shader_defs,
            ..Default::default()
        })
        .unwrap_or_else(|error| panic!("draw.wgsl with {definitions:?}:\n{}", error.emit_to_string(composer)))
}

/// Names of the module's entry points.
fn entry_points(module: &naga::Module) -> Vec<(naga::ShaderStage, String)> {
    module.entry_points.iter().map(|entry| (entry.stage, entry.name.clone())).collect()
}

#[test]
fn the_hair_shader_composes_with_bevy_and_validates_in_every_pass() {
    let mut composer = bevy_composer();
    let on = ShaderDefValue::Bool(true);
    let main_passes: [&[(&str, ShaderDefValue)]; 3] = [
        // 4× MSAA with alpha to coverage, tonemapped in the shader (an LDR camera).
        &[
            ("MULTISAMPLED", on),
            ("HAIR_MULTISAMPLED", on),
            ("HAIR_CAMERA_PREPASS", on),
            ("HAIR_MSAA_SAMPLES", ShaderDefValue::UInt(4)),
            ("ALPHA_TO_COVERAGE", on),
            ("TONEMAP_IN_SHADER", on),
            ("TONEMAP_METHOD_TONY_MC_MAPFACE", on),
            ("TONEMAPPING_LUT_TEXTURE_BINDING_INDEX", ShaderDefValue::UInt(22)),
            ("TONEMAPPING_LUT_SAMPLER_BINDING_INDEX", ShaderDefValue::UInt(23)),
            ("SHADOW_FILTER_METHOD_GAUSSIAN", on),
        ],
        // No multisampling (coverage dithered), HDR (tonemapped later).
        &[
            ("MAY_DISCARD", on),
            ("SHADOW_FILTER_METHOD_HARDWARE_2X2", on),
            ("HAIR_MSAA_SAMPLES", ShaderDefValue::UInt(1)),
        ],
        // 8× MSAA, orthographic view.
        &[
            ("MULTISAMPLED", on),
            ("HAIR_MULTISAMPLED", on),
            ("HAIR_CAMERA_PREPASS", on),
            ("HAIR_MSAA_SAMPLES", ShaderDefValue::UInt(8)),
            ("ALPHA_TO_COVERAGE", on),
            ("VIEW_PROJECTION_ORTHOGRAPHIC", on),
            ("SHADOW_FILTER_METHOD_TEMPORAL", on),
        ],
    ];
    for definitions in main_passes {
        let module = compose(&mut composer, ShaderType::Wgsl, definitions);
        let entries = entry_points(&module);
        assert!(entries.contains(&(naga::ShaderStage::Vertex, "vertex".into())), "{entries:?}");
        assert!(entries.contains(&(naga::ShaderStage::Fragment, "fragment".into())), "{entries:?}");
    }
    // Each with the fragment stage: Bevy runs it where there is something to write, depth clamping to
    // emulate, or (without saying `PREPASS_FRAGMENT`) a material that may discard. The hair's own
    // definitions as `HairMaterial::specialize` gives them.
    let (one, four) = (("HAIR_MSAA_SAMPLES", ShaderDefValue::UInt(1)), ("HAIR_MSAA_SAMPLES", ShaderDefValue::UInt(4)));
    let prepasses: [&[(&str, ShaderDefValue)]; 5] = [
        // A shadow map: depth only, whole ribbons.
        &[("PREPASS_PIPELINE", on), ("DEPTH_PREPASS", on), ("MAY_DISCARD", on), one],
        // A directional light's shadow map where depth clamping is emulated.
        &[
            ("PREPASS_PIPELINE", on),
            ("DEPTH_PREPASS", on),
            ("UNCLIPPED_DEPTH_ORTHO_EMULATION", on),
            ("PREPASS_FRAGMENT", on),
            one,
        ],
        // A camera's normal and motion-vector prepass, multisampled: the main pass's samples.
        &[
            ("PREPASS_PIPELINE", on),
            ("DEPTH_PREPASS", on),
            ("NORMAL_PREPASS", on),
            ("NORMAL_PREPASS_OR_DEFERRED_PREPASS", on),
            ("MOTION_VECTOR_PREPASS", on),
            ("PREPASS_FRAGMENT", on),
            ("HAIR_MULTISAMPLED", on),
            ("HAIR_CAMERA_PREPASS", on),
            four,
        ],
        // A camera's motion vectors without multisampling: whole pixels, as the main pass keeps them.
        &[
            ("PREPASS_PIPELINE", on),
            ("DEPTH_PREPASS", on),
            ("MOTION_VECTOR_PREPASS", on),
            ("PREPASS_FRAGMENT", on),
            ("HAIR_CAMERA_PREPASS", on),
            one,
        ],
        // A camera's depth prepass alone, multisampled.
        &[
            ("PREPASS_PIPELINE", on),
            ("DEPTH_PREPASS", on),
            ("MAY_DISCARD", on),
            ("HAIR_MULTISAMPLED", on),
            ("HAIR_CAMERA_PREPASS", on),
            four,
        ],
    ];
    for definitions in prepasses {
        let module = compose(&mut composer, ShaderType::Wgsl, definitions);
        let entries = entry_points(&module);
        assert!(entries.contains(&(naga::ShaderStage::Vertex, "vertex".into())), "{definitions:?}: {entries:?}");
        assert!(entries.contains(&(naga::ShaderStage::Fragment, "fragment".into())), "{definitions:?}: {entries:?}");
    }
}

#[test]
fn a_broken_hair_shader_is_caught() {
    // The check itself can fail: an undefined name in the shader is an error, not a pass.
    let mut composer = bevy_composer();
    let broken = HAIR_SHADER.replace("let clip_w =", "let clip_w = undefined_name +");
    let mut shader_defs = common_definitions();
    shader_defs.insert("ALPHA_TO_COVERAGE".into(), ShaderDefValue::Bool(true));
    let result = composer.make_naga_module(NagaModuleDescriptor {
        source: &broken,
        file_path: "broken.wgsl",
        shader_type: ShaderType::Wgsl,
        shader_defs,
        ..Default::default()
    });
    assert!(result.is_err(), "a shader with an undefined name composed");
}

/// The GPU follower shader (`src/render/followers.wgsl`, no imports), parsed and validated by naga with
/// WebGPU's capabilities.
fn validate_followers_shader(source: &str) -> Result<naga::Module, String> {
    let module = naga::front::wgsl::parse_str(source).map_err(|error| error.emit_to_string(source))?;
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty())
        .validate(&module)
        .map_err(|error| error.emit_to_string(source))?;
    Ok(module)
}

#[test]
fn the_follower_shader_validates_with_its_three_compute_passes() {
    let module =
        validate_followers_shader(include_str!("../../src/render/followers.wgsl")).unwrap_or_else(|e| panic!("{e}"));
    let mut entries = entry_points(&module);
    entries.sort();
    let compute = naga::ShaderStage::Compute;
    let names = ["draw", "frames", "place"];
    assert_eq!(entries, names.map(|name| (compute, name.to_string())));
}

#[test]
fn a_broken_follower_shader_is_caught() {
    let source = include_str!("../../src/render/followers.wgsl");
    let broken = source.replace("let m2 = cross(t, m1);", "let m2 = cross(t, m1, undefined_name);");
    assert_ne!(broken, source, "the line to break is in the shader");
    assert!(validate_followers_shader(&broken).is_err(), "a shader with an undefined name validated");
}

#[test]
fn the_strand_step_shader_validates_with_webgpu_capabilities() {
    // WebGPU's capabilities only (no f64, no subgroups): the step runs wherever wgpu does.
    let module = validate_followers_shader(include_str!("../../src/gpu/step.wgsl")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(entry_points(&module), [(naga::ShaderStage::Compute, "step".to_string())]);
}
