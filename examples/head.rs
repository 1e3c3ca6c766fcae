//! A head with a full head of simulated hair that you can orbit, move, animate, restyle and tune.
//!
//! ```sh
//! cargo run --release --features examples,egui --example head     # with the live panel
//! cargo run --release --features examples --example head   # without it (statistics in the title)
//! ```
//!
//! Drag with the left mouse button to orbit and scroll to zoom. Arrow keys or WASD walk the body, Q and E
//! turn it, Space cycles the head's animation (still, nod, shake, turn, sway, flick), 1 to 5 pick the hair style, K
//! combs it along the scalp or grows it straight out, C shows the colliders the hair rests on (skull,
//! face, neck, shoulders, torso), V turns a gusty, turbulent breeze on and off (tune it in the panel), L
//! switches between rendered hair, gizmo lines and both. The strands step on the GPU where the adapter
//! can (`HairGpuPlugin`, part of `HairPlugins`), with the followers placed and the hair drawn from there;
//! `--gpu off` (or the Scene panel's switch) steps them on the CPU.
//!
//! Picture mode, for machines without a display (under `xvfb-run` with Mesa's software Vulkan driver,
//! `mesa-vulkan-drivers` on Debian and Ubuntu, with `xvfb`): render a number of frames
//! of exactly 1/60 s each (one simulation step per frame, however slow the renderer; the panel's frame
//! rate then reads this clock's 60), save a PNG with Bevy's screenshot API and exit. The rendered hair
//! takes seconds per frame in software, so it is drawn only in the first and last 8 frames
//! (`--draw-every-frame on` draws it throughout, to time it).
//!
//! ```sh
//! cargo run --release --features examples,egui --example head -- --screenshot shot.png --frames 240 \
//!     --style curly --animate shake --strands 2000 --segments 32 --yaw 30
//! ```

use std::f32::consts::{PI, TAU};
use std::time::Duration;

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::light::{CascadeShadowConfigBuilder, DirectionalLightShadowMap};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::groom::{FileStrand, GroomedStrand, PlacedGroomFile};
use bevy_hair_sim::prelude::*;

use hair_sim_support::example_scene::{BODY, EYE_RADIUS, EYES, FACE, NECK_HEIGHT, SCALP};

fn main() {
    let options = match Options::from_args(std::env::args().skip(1)) {
        Ok(options) => options,
        Err(message) => {
            eprintln!("{message}\n\n{}", Options::USAGE);
            std::process::exit(2);
        }
    };
    let window = Window { title: "bevy_hair_sim".into(), resolution: (1280, 800).into(), ..default() };
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(WindowPlugin { primary_window: Some(window), ..default() })
            .set(TaskPoolPlugin { task_pool_options: HairPlugins::task_pool_options() }),
        HairPlugins::default(),
    ));
    app.insert_resource(Time::<Fixed>::from_hz(60.0))
        .insert_resource(HairGpuSettings { enabled: options.gpu, ..default() })
        .insert_resource(ClearColor(Color::srgb(0.11, 0.12, 0.14)))
        .insert_resource(AnimationClock { animation: options.animation, seconds: 0.0 })
        .insert_resource(HairSettings {
            integrator: options.integrator,
            volume: options.volume,
            style_hold: HairStyleHold { rate: options.style_hold, ..default() },
            ..default()
        })
        .insert_resource(HairCpuBudget { milliseconds: options.budget, ..default() })
        .insert_resource(breeze(options.wind))
        .add_systems(Startup, spawn_scene)
        .insert_resource(DirectionalLightShadowMap { size: 4096 })
        .add_systems(Update, (animate_head, walk_body, hair_keys, switch_groom, show_statistics, switch_drawing));
    #[cfg(feature = "egui")]
    {
        use bevy_egui::input::egui_wants_any_pointer_input;
        app.add_plugins(HairPanelPlugin)
            .add_systems(Update, orbit_camera.run_if(not(egui_wants_any_pointer_input)))
            .add_systems(bevy_egui::EguiPrimaryContextPass, scene_panel);
    }
    #[cfg(not(feature = "egui"))]
    app.add_systems(Update, orbit_camera);
    if options.screenshot.is_some() {
        app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / 60.0)))
            .add_systems(Update, take_picture.after(switch_drawing));
    }
    app.insert_resource(options).run();
}

/// Command-line options: the scene's start and picture mode.
#[derive(Resource, Debug, Clone)]
struct Options {
    /// Save a picture here after `frames` frames and exit.
    screenshot: Option<String>,
    frames: u32,
    style: HairStyle,
    animation: Animation,
    strands: usize,
    /// Follower hairs per simulated strand.
    followers: usize,
    /// How much each guide's followers gather onto it towards the tip, 0 to 1 (`HairGroom::follower_clumping`).
    clumping: f32,
    /// How far followers stray across their guide towards the tip, m (`HairGroom::follower_scatter`).
    scatter: f32,
    segments: usize,
    /// Camera angle around the head, degrees from straight in front (positive: the head's left).
    yaw_degrees: f32,
    /// Camera distance from the head, m.
    distance: f32,
    /// Camera elevation, degrees above the head.
    pitch_degrees: f32,
    /// Whether the colliders are drawn as wireframes from the start (C toggles it).
    draw_colliders: bool,
    /// Whether the head starts with the groom from `assets/grooms/Ratboy_mohawk.tfx` instead of the
    /// procedural one (G toggles it).
    file_groom: bool,
    /// Whether the procedural groom is combed along the scalp (K toggles it).
    combed: bool,
    /// Mean wind speed, m/s, from the head's left (V toggles a breeze).
    wind: f32,
    integrator: bevy_hair_sim::rod::Integrator,
    /// Hair–hair interaction: on with its velocity smoothing, plus a volume pressure if given.
    volume: HairVolume,
    /// How fast the hair is drawn back to its groomed style near the roots, 1/s (0: free).
    style_hold: f32,
    /// How hair is drawn at the start (L cycles it).
    drawing: Drawing,
    /// Picture mode: whether the rendered hair is drawn in every frame, not only in the first and last
    /// [`DRAWN_PICTURE_FRAMES`] (for timing the renderer).
    draw_every_frame: bool,
    /// The rendered hair's look (a preset of [`HairAppearance::presets`]).
    appearance: HairAppearance,
    /// A level of detail to keep (`None`: chosen from the camera's distance).
    detail: Option<HairDetailLevel>,
    /// The hair's CPU budget per fixed step, ms (`None`: no budget; see [`HairCpuBudget`]).
    budget: Option<f32>,
    /// Whether the camera blurs what moves (Bevy's `MotionBlur`, from the hair's motion vectors).
    motion_blur: bool,
    /// Whether the camera smooths edges over frames (Bevy's `TemporalAntiAliasing`, MSAA off) instead of
    /// with 4× MSAA.
    taa: bool,
    /// Whether the GPU steps the hair (`HairGpuPlugin`).
    gpu: bool,
    /// `HairAppearance::highlight_filtering` over the colour's (`None`: the default).
    highlight_filtering: Option<f32>,
}

/// How the example draws hair: rendered strands, gizmo lines, or both over each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Drawing {
    Rendered,
    Lines,
    Both,
}

impl Drawing {
    const ALL: [Drawing; 3] = [Self::Rendered, Self::Lines, Self::Both];

    fn name(self) -> &'static str {
        match self {
            Self::Rendered => "hair",
            Self::Lines => "lines",
            Self::Both => "both",
        }
    }
}

impl Options {
    const USAGE: &str = "usage: head [--screenshot PATH] [--frames N] [--style straight|wavy|curly|short|long]
            [--animate still|nod|shake|turn|sway|flick] [--strands N] [--followers N] [--clumping 0-1] [--scatter MM] [--segments N] [--yaw DEGREES]
            [--pitch DEGREES] [--distance M]
            [--colliders on|off] [--groom procedural|ratboy] [--combing on|off] [--wind M/S]
            [--integrator bdf2|euler] [--grid on|off] [--pressure PA] [--hold 1/S] [--draw hair|lines|both]
            [--draw-every-frame on|off] [--detail auto|full|2|4|carried] [--budget MS] [--gpu on|off] [--motion-blur on|off] [--taa on|off]
            [--color black|dark brown|brown|auburn|red|blonde|light blonde|white] [--highlight-filtering 0-4]";

    /// The procedural groom these options ask for, on the example's scalp.
    fn procedural_groom(&self) -> HairGroom {
        HairGroom {
            scalp: SCALP,
            strand_count: self.strands,
            segments: self.segments,
            style: self.style,
            seed: 1,
            combing: self.combed.then(Combing::default),
            followers_per_guide: self.followers,
            follower_clumping: self.clumping,
            follower_scatter: self.scatter,
            ..default()
        }
    }

    fn from_args(mut args: impl Iterator<Item = String>) -> Result<Self, String> {
        let groom = HairGroom::default();
        let mut options = Self {
            screenshot: None,
            frames: 240,
            style: groom.style,
            animation: Animation::Still,
            strands: groom.strand_count,
            followers: 10,
            clumping: groom.follower_clumping,
            scatter: groom.follower_scatter,
            segments: groom.segments,
            yaw_degrees: 35.0,
            distance: 0.85,
            pitch_degrees: 7.0,
            draw_colliders: false,
            file_groom: false,
            combed: groom.combing.is_some(),
            wind: 0.0,
            integrator: HairSettings::default().integrator,
            // The example shows the hair–hair grid: its velocity smoothing (the pressure with --pressure).
            volume: HairVolume { enabled: true, ..default() },
            // The style held, strongest at the roots: shaken, 0.55 % of the guides stray instead of 38 %
            // (`benchmark coverage`); `--hold 0` lets the hair go.
            style_hold: 200.0,
            drawing: Drawing::Rendered,
            draw_every_frame: false,
            appearance: HairAppearance::default(),
            detail: None,
            budget: None,
            gpu: true,
            highlight_filtering: None,
            motion_blur: false,
            taa: false,
        };
        while let Some(flag) = args.next() {
            let value = args.next().ok_or_else(|| format!("{flag} needs a value"))?;
            let number = |what: &str| value.parse::<f32>().map_err(|_| format!("{flag} needs {what}, got {value:?}"));
            let switch = || match value.as_str() {
                "on" => Ok(true),
                "off" => Ok(false),
                _ => Err(format!("{flag} needs on or off, got {value:?}")),
            };
            match flag.as_str() {
                "--screenshot" => options.screenshot = Some(value.clone()),
                "--frames" => options.frames = number("a count")? as u32,
                "--strands" => options.strands = number("a count")? as usize,
                "--followers" => options.followers = number("a count")? as usize,
                "--clumping" => options.clumping = number("a share from 0 to 1")?,
                "--scatter" => options.scatter = 1e-3 * number("a distance in mm")?,
                "--segments" => options.segments = number("a count")? as usize,
                "--yaw" => options.yaw_degrees = number("an angle in degrees")?,
                "--pitch" => options.pitch_degrees = number("an angle in degrees")?,
                "--distance" => options.distance = number("a distance in m")?.clamp(0.3, 5.0),
                "--wind" => options.wind = number("a speed in m/s")?,
                "--pressure" => options.volume.stiffness = number("a pressure in Pa")?,
                "--grid" => options.volume.enabled = switch()?,
                "--hold" => options.style_hold = number("a rate in 1/s")?,
                "--gpu" => options.gpu = switch()?,
                "--motion-blur" => options.motion_blur = switch()?,
                "--taa" => options.taa = switch()?,
                "--integrator" => {
                    options.integrator = match value.as_str() {
                        "bdf2" => bevy_hair_sim::rod::Integrator::Bdf2,
                        "euler" => bevy_hair_sim::rod::Integrator::BackwardEuler,
                        _ => return Err(format!("--integrator needs bdf2 or euler, got {value:?}")),
                    }
                }
                "--colliders" => options.draw_colliders = switch()?,
                "--combing" => options.combed = switch()?,
                "--groom" => {
                    options.file_groom = match value.as_str() {
                        "ratboy" => true,
                        "procedural" => false,
                        _ => return Err(format!("--groom needs procedural or ratboy, got {value:?}")),
                    }
                }
                "--style" => {
                    options.style = HairStyle::ALL
                        .into_iter()
                        .find(|style| style.name() == value)
                        .ok_or_else(|| format!("unknown style {value:?}"))?
                }
                "--draw-every-frame" => options.draw_every_frame = switch()?,
                "--draw" => {
                    options.drawing = Drawing::ALL
                        .into_iter()
                        .find(|drawing| drawing.name() == value)
                        .ok_or_else(|| format!("--draw needs hair, lines or both, got {value:?}"))?
                }
                "--budget" => options.budget = Some(number("milliseconds per fixed step")?),
                "--detail" => {
                    options.detail = match value.as_str() {
                        "auto" => None,
                        "full" => Some(HairDetailLevel::FULL),
                        "carried" => Some(HairDetailLevel::Carried),
                        interval => Some(HairDetailLevel::Stepped(interval.parse().map_err(|_| {
                            format!("--detail needs auto, full, a step interval or carried, got {value:?}")
                        })?)),
                    }
                }
                "--color" => {
                    options.appearance = HairAppearance::presets()
                        .into_iter()
                        .find(|(name, _)| *name == value)
                        .map(|(_, appearance)| appearance)
                        .ok_or_else(|| format!("unknown hair colour {value:?}"))?
                }
                "--highlight-filtering" => {
                    options.highlight_filtering = Some(
                        value
                            .parse()
                            .map_err(|_| format!("--highlight-filtering needs a number from 0 to 4, got {value:?}"))?,
                    )
                }
                "--animate" => {
                    options.animation = Animation::ALL
                        .into_iter()
                        .find(|animation| animation.name() == value)
                        .ok_or_else(|| format!("unknown animation {value:?}"))?
                }
                _ => return Err(format!("unknown option {flag:?}")),
            }
        }
        Ok(options)
    }
}

/// How the head moves by itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Animation {
    Still,
    Nod,
    Shake,
    Turn,
    Sway,
    /// Still for 1 s, a quick turn of 0.8 rad over 0.3 s, then still: the hair swings and settles.
    Flick,
}

impl Animation {
    const ALL: [Animation; 6] = [Self::Still, Self::Nod, Self::Shake, Self::Turn, Self::Sway, Self::Flick];

    fn name(self) -> &'static str {
        match self {
            Self::Still => "still",
            Self::Nod => "nod",
            Self::Shake => "shake",
            Self::Turn => "turn",
            Self::Sway => "sway",
            Self::Flick => "flick",
        }
    }

    /// The head's rotation on its neck and the body's sideways offset (m), `seconds` into the animation.
    fn pose(self, seconds: f32) -> (Quat, f32) {
        let wave = |hertz: f32| (TAU * hertz * seconds).sin();
        match self {
            Self::Still => (Quat::IDENTITY, 0.0),
            Self::Nod => (Quat::from_rotation_x(0.35 * wave(1.2)), 0.0),
            Self::Shake => (Quat::from_rotation_y(0.7 * wave(1.8)), 0.0),
            Self::Turn => (Quat::from_rotation_y(1.2 * wave(0.3)), 0.0),
            Self::Sway => (Quat::from_rotation_z(0.15 * wave(0.7)), 0.12 * wave(0.7)),
            Self::Flick => {
                let t = ((seconds - 1.0) / 0.3).clamp(0.0, 1.0);
                (Quat::from_rotation_y(0.8 * t * t * (3.0 - 2.0 * t)), 0.0)
            }
        }
    }
}

/// The animation playing and how long it has played, s.
#[derive(Resource)]
struct AnimationClock {
    animation: Animation,
    seconds: f32,
}

/// The body: walked and turned with the keyboard; the head sits on it.
#[derive(Component, Default)]
struct Body {
    position: Vec3,
    heading: f32,
    sway: f32,
}

/// The camera's orbit around the head.
#[derive(Component)]
struct Orbit {
    yaw: f32,
    pitch: f32,
    distance: f32,
}

fn spawn_scene(
    mut commands: Commands,
    options: Res<Options>,
    assets: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut gizmos: ResMut<GizmoConfigStore>,
) {
    let (config, hair_gizmos) = gizmos.config_mut::<HairGizmos>();
    config.line.width = 1.5;
    hair_gizmos.draw_colliders = options.draw_colliders;
    let yaw = PI + options.yaw_degrees.to_radians();
    let camera = commands
        .spawn((
            Camera3d::default(),
            Transform::default(),
            Orbit { yaw, pitch: options.pitch_degrees.to_radians(), distance: options.distance },
        ))
        .id();
    if options.motion_blur {
        // Blurred along each pixel's motion vector over half a frame: the hair's come from where it was
        // drawn the frame before.
        commands.entity(camera).insert(bevy::post_process::motion_blur::MotionBlur::default());
    }
    if options.taa {
        // Each hair thinner than a pixel is drawn on that share of its pixels, a new draw for each of the
        // view's eight jitters; TAA averages them into the hair's coverage (it needs MSAA off).
        commands.entity(camera).insert((bevy::anti_alias::taa::TemporalAntiAliasing::default(), Msaa::Off));
    }
    // The key light casts the hair's shadows, on the head and on the hair itself: one cascade over the
    // 3 m around the camera, so that a shadow texel (4096² map) is under a millimetre.
    commands.spawn((
        DirectionalLight { illuminance: 9000.0, shadow_maps_enabled: true, ..default() },
        Transform::from_xyz(-1.0, 3.0, -2.0).looking_at(Vec3::ZERO, Vec3::Y),
        CascadeShadowConfigBuilder { num_cascades: 1, maximum_distance: 3.0, ..default() }.build(),
    ));
    // A dim fill light from the other side, so that the shadowed side of the hair keeps its highlights.
    commands.spawn((PointLight { intensity: 40_000.0, range: 10.0, ..default() }, Transform::from_xyz(1.2, 2.0, 1.0)));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(8.0, 8.0))),
        MeshMaterial3d(materials.add(Color::srgb(0.25, 0.26, 0.28))),
    ));

    let skin = materials.add(Color::srgb(0.87, 0.69, 0.58));
    let shirt = materials.add(Color::srgb(0.2, 0.3, 0.45));
    let white = materials.add(Color::srgb(0.95, 0.95, 0.95));
    let iris = materials.add(Color::srgb(0.15, 0.25, 0.35));
    let mut part = |mesh: Mesh, material: &Handle<StandardMaterial>, transform: Transform| {
        (Mesh3d(meshes.add(mesh)), MeshMaterial3d(material.clone()), transform)
    };
    let scalp = SCALP;
    let groom = options.procedural_groom();
    let body = commands.spawn((Body::default(), Transform::default(), Visibility::default())).id();
    let head = commands
        .spawn((
            HairHead,
            HairAppearance {
                highlight_filtering: options.highlight_filtering.unwrap_or(options.appearance.highlight_filtering),
                ..options.appearance.clone()
            },
            Transform::from_xyz(0.0, NECK_HEIGHT, 0.0),
            Visibility::default(),
            ChildOf(body),
        ))
        .id();
    if let Some(level) = options.detail {
        commands.entity(head).insert(HairDetail::fixed(level));
    }
    if options.file_groom {
        commands.entity(head).insert(ratboy_groom(&assets, options.segments));
    } else {
        commands.entity(head).insert(groom);
    }
    // The hair rests on the skull, face, neck, shoulders and torso: each mesh carries a collider of its
    // shape (the unit spheres scaled into ellipsoids by their transforms), tied to the head.
    let collider = |shape: HairCollider| (shape, HairColliderOf(head));
    let ellipsoid = |semi_axes: Vec3, centre: Vec3| Transform::from_translation(centre).with_scale(semi_axes);
    let [neck, shoulders, torso] = BODY;
    commands.entity(body).with_children(|body| {
        let capsule =
            |part: &hair_sim_support::example_scene::BodyCapsule| Capsule3d::new(part.radius, 2.0 * part.half_length);
        body.spawn((part(capsule(&torso).into(), &shirt, torso.transform()), collider(torso.collider())));
        body.spawn((part(capsule(&shoulders).into(), &shirt, shoulders.transform()), collider(shoulders.collider())));
        body.spawn((part(Cylinder::new(neck.radius, 0.14).into(), &skin, neck.transform()), collider(neck.collider())));
    });
    commands.entity(head).with_children(|head| {
        head.spawn((
            part(Sphere::new(1.0).mesh().uv(48, 24), &skin, ellipsoid(scalp.semi_axes, scalp.centre)),
            collider(HairCollider::sphere(1.0)),
        ));
        // Face and jaw, in front of and below the skull (the face looks along −Z).
        head.spawn((
            part(Sphere::new(1.0).mesh().uv(32, 16), &skin, ellipsoid(FACE.1, FACE.0)),
            collider(HairCollider::sphere(1.0)),
        ));
        for eye in EYES {
            head.spawn(part(Sphere::new(EYE_RADIUS).into(), &white, Transform::from_translation(eye)));
            let iris_centre = eye - Vec3::Z * (EYE_RADIUS - 0.0015);
            head.spawn(part(Sphere::new(0.5 * EYE_RADIUS).into(), &iris, Transform::from_translation(iris_centre)));
        }
        head.spawn(part(
            Capsule3d::new(0.011, 0.03).into(),
            &skin,
            Transform::from_xyz(0.0, 0.085, -0.102).with_rotation(Quat::from_rotation_x(0.35)),
        ));
        for side in [-1.0, 1.0] {
            head.spawn(part(
                Sphere::new(1.0).mesh().uv(16, 8),
                &skin,
                ellipsoid(Vec3::new(0.012, 0.028, 0.018), Vec3::new(side * 0.079, 0.1, 0.01)),
            ));
        }
    });
}

fn orbit_camera(
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    heads: Query<&GlobalTransform, With<HairHead>>,
    mut cameras: Query<(&mut Transform, &mut Orbit)>,
) {
    let focus =
        heads.iter().next().map_or(Vec3::new(0.0, NECK_HEIGHT, 0.0), |head| head.translation()) + 0.06 * Vec3::Y;
    for (mut transform, mut orbit) in &mut cameras {
        if buttons.pressed(MouseButton::Left) {
            orbit.yaw -= 0.005 * motion.delta.x;
            orbit.pitch = (orbit.pitch + 0.005 * motion.delta.y).clamp(-1.4, 1.4);
        }
        orbit.distance = (orbit.distance * (1.0 - 0.1 * scroll.delta.y)).clamp(0.3, 5.0);
        let offset = Quat::from_euler(EulerRot::YXZ, orbit.yaw, -orbit.pitch, 0.0) * Vec3::Z * orbit.distance;
        *transform = Transform::from_translation(focus + offset).looking_at(focus, Vec3::Y);
    }
}

/// Plays the head's animation on its neck; Space picks the next one.
fn animate_head(
    time: Res<Time>,
    keys: Res<ButtonInput<KeyCode>>,
    mut clock: ResMut<AnimationClock>,
    mut heads: Query<&mut Transform, (With<HairHead>, Without<Body>)>,
    mut bodies: Query<&mut Body>,
) {
    if keys.just_pressed(KeyCode::Space) {
        let next = Animation::ALL.iter().position(|&animation| animation == clock.animation).map_or(0, |i| i + 1);
        clock.animation = Animation::ALL[next % Animation::ALL.len()];
        clock.seconds = 0.0;
    }
    clock.seconds += time.delta_secs();
    let (rotation, sway) = clock.animation.pose(clock.seconds);
    for mut head in &mut heads {
        head.rotation = rotation;
    }
    for mut body in &mut bodies {
        body.sway = sway;
    }
}

/// Walks the body with the arrow keys or WASD and turns it with Q and E.
fn walk_body(time: Res<Time>, keys: Res<ButtonInput<KeyCode>>, mut bodies: Query<(&mut Transform, &mut Body)>) {
    // −1, 0 or 1 from a pair of key sets.
    let axis = |positive: &[KeyCode], negative: &[KeyCode]| {
        f32::from(u8::from(keys.any_pressed(positive.iter().copied())))
            - f32::from(u8::from(keys.any_pressed(negative.iter().copied())))
    };
    let forward = axis(&[KeyCode::ArrowUp, KeyCode::KeyW], &[KeyCode::ArrowDown, KeyCode::KeyS]);
    let right = axis(&[KeyCode::ArrowRight, KeyCode::KeyD], &[KeyCode::ArrowLeft, KeyCode::KeyA]);
    let turn = axis(&[KeyCode::KeyQ], &[KeyCode::KeyE]);
    let step = time.delta_secs();
    for (mut transform, mut body) in &mut bodies {
        let facing = Quat::from_rotation_y(body.heading);
        body.position += facing * Vec3::new(right, 0.0, -forward) * 0.8 * step;
        body.heading += 2.0 * step * turn;
        transform.translation = body.position + facing * Vec3::X * body.sway;
        transform.rotation = Quat::from_rotation_y(body.heading);
    }
}

/// TressFX's Ratboy mohawk (`assets/grooms/`, MIT licence beside it), scaled onto the example's skull.
fn ratboy_groom(assets: &AssetServer, segments: usize) -> HairGroomFile {
    let placement = GroomPlacement {
        metres_per_unit: RATBOY_SCALE,
        transform: Transform::from_translation(RATBOY_OFFSET).with_rotation(Quat::from_rotation_y(PI)),
        segments,
        ..default()
    };
    HairGroomFile::new(assets.load("grooms/Ratboy_mohawk.tfx")).with_placement(placement)
}

/// Metres per unit of the Ratboy groom: its head is about four times as tall as the example's. Its roots
/// lie on a straight line from the nape to the crown of that tall head, which the example's round skull
/// cannot follow: the crown's roots sit on the scalp, the nape's inside the skull.
const RATBOY_SCALE: f32 = 0.25;

/// Where the Ratboy groom's origin goes in the head's space, m.
const RATBOY_OFFSET: Vec3 = Vec3::new(0.0, 0.0, 0.0);

/// The strands grown from a groom, procedural or from a file.
type GrownStrands<'w, 's> = Query<'w, 's, Entity, Or<(With<GroomedStrand>, With<FileStrand>)>>;

/// G switches the head between the procedural groom and the Ratboy file.
fn switch_groom(
    mut commands: Commands,
    keys: Res<ButtonInput<KeyCode>>,
    options: Res<Options>,
    assets: Res<AssetServer>,
    heads: Query<(Entity, Has<HairGroomFile>), With<HairHead>>,
    strands: GrownStrands,
) {
    if !keys.just_pressed(KeyCode::KeyG) {
        return;
    }
    strands.iter().for_each(|strand| commands.entity(strand).despawn());
    for (head, from_file) in &heads {
        if from_file {
            let groom = options.procedural_groom();
            commands.entity(head).remove::<(HairGroomFile, PlacedGroomFile)>().insert(groom);
        } else {
            commands.entity(head).remove::<HairGroom>().insert(ratboy_groom(&assets, options.segments));
        }
    }
}

/// A breeze from the head's left (+x) at `speed` m/s, gusting by a third of it, with eddies.
fn breeze(speed: f32) -> HairWind {
    HairWind {
        velocity: Vec3::new(speed, 0.0, 0.0),
        gusts: speed / 3.0,
        gust_period: 2.0,
        turbulence: speed / 6.0,
        turbulence_scale: 0.3,
        ..default()
    }
}

/// Keys 1 to 5 pick the hair style; K combs it or not; C shows or hides the colliders; V turns the
/// breeze on (3 m/s) and off.
fn hair_keys(
    keys: Res<ButtonInput<KeyCode>>,
    mut grooms: Query<&mut HairGroom>,
    mut gizmos: ResMut<GizmoConfigStore>,
    mut wind: ResMut<HairWind>,
) {
    if keys.just_pressed(KeyCode::KeyV) {
        *wind = if wind.is_calm() { breeze(3.0) } else { HairWind::default() };
    }
    if keys.just_pressed(KeyCode::KeyC) {
        let hair_gizmos = gizmos.config_mut::<HairGizmos>().1;
        hair_gizmos.draw_colliders = !hair_gizmos.draw_colliders;
    }
    if keys.just_pressed(KeyCode::KeyK) {
        for mut groom in &mut grooms {
            groom.combing = if groom.combing.is_some() { None } else { Some(Combing::default()) };
        }
    }
    let keys_and_styles = [KeyCode::Digit1, KeyCode::Digit2, KeyCode::Digit3, KeyCode::Digit4, KeyCode::Digit5]
        .into_iter()
        .zip(HairStyle::ALL);
    for (_, style) in keys_and_styles.filter(|(key, _)| keys.just_pressed(*key)) {
        for mut groom in &mut grooms {
            groom.style = style;
        }
    }
}

fn show_statistics(
    time: Res<Time<Real>>,
    statistics: Res<HairStatistics>,
    gpu: Res<HairGpuStatus>,
    clock: Res<AnimationClock>,
    mut windows: Query<&mut Window>,
    mut since_update: Local<f32>,
) {
    *since_update += time.delta_secs();
    if *since_update < 0.5 {
        return;
    }
    *since_update = 0.0;
    let on_gpu = if gpu.strands > 0 { format!(" ({} on the GPU)", gpu.strands) } else { String::new() };
    let title = format!(
        "bevy_hair_sim: {} strands{on_gpu} + {} followers, {} nodes ({} in contact), step {:.1} ms, {:.0} fps, \
         strain {:.1e}, {} faults, head: {} (Space)",
        statistics.strands + gpu.strands,
        statistics.followers,
        statistics.nodes,
        statistics.contacts,
        1e3 * statistics.step_seconds,
        1.0 / time.delta_secs().max(1e-6),
        statistics.max_strain,
        statistics.faults,
        clock.animation.name(),
    );
    for mut window in &mut windows {
        window.title.clone_from(&title);
    }
}

/// The scene's own controls, next to the hair panel.
#[cfg(feature = "egui")]
fn scene_panel(
    mut contexts: bevy_egui::EguiContexts,
    mut clock: ResMut<AnimationClock>,
    mut gpu: ResMut<HairGpuSettings>,
    gpu_status: Res<HairGpuStatus>,
) -> Result {
    use bevy_egui::egui;
    egui::Window::new("Scene").anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0]).show(contexts.ctx_mut()?, |ui| {
        let mut enabled = gpu.enabled;
        if ui.checkbox(&mut enabled, "step on the GPU").changed() {
            gpu.enabled = enabled;
        }
        if gpu.enabled {
            let age = gpu_status.read_back_age.map_or("not read back".to_string(), |age| format!("read back {age} steps old"));
            // The plugin's own CPU time, wgpu's submissions and polls left out (on a software adapter, the
            // GPU's work itself).
            let cpu = 1e3
                * (gpu_status.main_thread_seconds + gpu_status.render_thread_seconds
                    - gpu_status.render_driver_seconds);
            ui.label(format!("{} strands on the GPU, {age}; CPU {cpu:.2} ms", gpu_status.strands));
            if let Some(error) = &gpu_status.error {
                ui.colored_label(egui::Color32::LIGHT_RED, error);
            }
        }
        ui.horizontal_wrapped(|ui| {
            ui.label("head:");
            for animation in Animation::ALL {
                if ui.selectable_label(clock.animation == animation, animation.name()).clicked() {
                    (clock.animation, clock.seconds) = (animation, 0.0);
                }
            }
        });
        ui.label("drag: orbit · scroll: zoom · WASD/arrows: walk · Q/E: turn · Space: next animation · 1–5: style · K: combed · G: Ratboy groom · C: colliders · L: hair / lines / both");
    });
    Ok(())
}

/// L cycles how hair is drawn: rendered, gizmo lines, both. The start comes from `--draw`; in between, the
/// panel's switches are left alone. The lines draw the followers from the CPU's placement, so the heads ask
/// for it while lines are drawn (the renderer places them on the GPU).
fn switch_drawing(
    mut commands: Commands,
    keys: Res<ButtonInput<KeyCode>>,
    options: Res<Options>,
    mut drawing: Local<Option<Drawing>>,
    mut gizmos: ResMut<GizmoConfigStore>,
    mut hair_meshes: Query<(&mut Visibility, Ref<HairMesh>)>,
    heads: Query<Entity, With<HairHead>>,
) {
    let new_meshes = hair_meshes.iter().any(|(_, mesh)| mesh.is_added());
    let current = drawing.unwrap_or(options.drawing);
    let next = if keys.just_pressed(KeyCode::KeyL) {
        let index = Drawing::ALL.iter().position(|&d| d == current).map_or(0, |i| i + 1);
        Drawing::ALL[index % Drawing::ALL.len()]
    } else {
        current
    };
    if drawing.is_some() && next == current && !new_meshes {
        return;
    }
    *drawing = Some(next);
    gizmos.config_mut::<HairGizmos>().1.draw_strands = next != Drawing::Rendered;
    for head in &heads {
        if next == Drawing::Rendered {
            commands.entity(head).remove::<PlaceFollowersOnCpu>();
        } else {
            commands.entity(head).insert(PlaceFollowersOnCpu);
        }
    }
    let shown = if next == Drawing::Lines { Visibility::Hidden } else { Visibility::Inherited };
    for (mut visibility, _) in &mut hair_meshes {
        visibility.set_if_neq(shown);
    }
}

/// Frames at the start (while the renderer compiles its pipelines) and before the picture in which the
/// rendered hair is drawn; in between it is hidden, so that a software renderer spends its time on the
/// frames that count. The simulation runs all along.
const DRAWN_PICTURE_FRAMES: u32 = 8;

/// Picture mode: after the asked number of frames, saves a screenshot and exits once it is written.
fn take_picture(
    mut commands: Commands,
    options: Res<Options>,
    mut frames: Local<u32>,
    mut hair_meshes: Query<&mut Visibility, With<HairMesh>>,
) {
    *frames += 1;
    let drawn = options.drawing != Drawing::Lines
        && (options.draw_every_frame
            || *frames <= DRAWN_PICTURE_FRAMES
            || *frames + DRAWN_PICTURE_FRAMES >= options.frames);
    let shown = if drawn { Visibility::Inherited } else { Visibility::Hidden };
    hair_meshes.iter_mut().for_each(|mut visibility| {
        visibility.set_if_neq(shown);
    });
    if *frames != options.frames {
        return;
    }
    let Some(path) = options.screenshot.clone() else {
        return;
    };
    commands.spawn(Screenshot::primary_window()).observe(save_to_disk(path)).observe(
        |_: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
            exit.write(AppExit::Success);
        },
    );
}
