//! The benchmark scene, shared by `benches/hair_step.rs` and `examples/benchmark.rs`: a headless app with
//! the real plugin, one head with `strands` straight 25 cm human hairs of `edges` edges (radius 40 µm,
//! E = 3.5 GPa, ρ = 1300 kg/m³), gravity on, the head swaying and turning, one fixed step of 1/60 s per
//! update; optionally up to 5 colliders (skull, face, neck, shoulders, torso) that the hair rests on.

use bevy::app::TaskPoolPlugin;
use bevy::prelude::*;
use bevy::tasks::available_parallelism;
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::detail::HeadsByDetail;
use bevy_hair_sim::prelude::*;

/// Length of every strand, m.
pub const HAIR_LENGTH: f32 = 0.25;
/// Steps run before measuring: the hair falls from straight out and starts to swing.
pub const WARM_UP_STEPS: usize = 60;

/// The colliders [`Scene::with_colliders`] adds, in order: the skull and face turn with the head, the
/// neck, shoulders and torso stay below it. Positions are relative to the head's rest position, m.
fn body_colliders() -> [(HairCollider, Transform, bool); 5] {
    [
        (HairCollider::sphere(0.1), Transform::default(), true),
        (HairCollider::ellipsoid(Vec3::new(0.062, 0.075, 0.07)), Transform::from_xyz(0.0, -0.055, -0.035), true),
        (HairCollider::capsule(0.045, 0.05), Transform::from_xyz(0.0, -0.15, 0.0), false),
        (
            HairCollider::capsule(0.06, 0.12),
            Transform::from_xyz(0.0, -0.24, 0.0).with_rotation(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2)),
            false,
        ),
        (HairCollider::capsule(0.12, 0.35), Transform::from_xyz(0.0, -0.67, 0.0), false),
    ]
}

/// A hair scene ready to step.
pub struct Scene {
    pub app: App,
    pub head: Entity,
    step: usize,
}

impl Scene {
    /// The scene with `threads` compute threads (`None`: one per core).
    pub fn new(strands: usize, edges: usize, threads: Option<usize>) -> Self {
        let mut app = Self::app(threads);
        let roots = Scalp::default().roots(strands).expect("the default scalp holds any count");
        let head = app
            .world_mut()
            .spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0)))
            .with_related_entities::<StrandOf>(|head| {
                for root in roots {
                    head.spawn(HairStrand::straight(root.position, root.normal, HAIR_LENGTH, edges));
                }
            })
            .id();
        Self { app, head, step: 0 }
    }

    /// A headless app with the hair plugin on `threads` compute threads (`None`: one per core), one fixed
    /// step of 1/60 s per update, its clock started.
    pub fn app(threads: Option<usize>) -> App {
        let threads = threads.unwrap_or_else(available_parallelism);
        let mut app = App::new();
        app.add_plugins((
            MinimalPlugins
                .set(TaskPoolPlugin { task_pool_options: HairPlugins::task_pool_options_with_threads(threads) }),
            HairPlugins::default(),
        ))
        .insert_resource(Time::<Fixed>::from_hz(60.0))
        .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
        app.finish();
        app.cleanup();
        app.update();
        app
    }

    /// Adds the first `count` (at most 5) of the skull, face, neck, shoulders and torso colliders.
    pub fn with_colliders(mut self, count: usize) -> Self {
        let head = self.head;
        let head_position = Vec3::new(0.0, 1.6, 0.0);
        for (collider, transform, on_head) in body_colliders().into_iter().take(count) {
            let world = self.app.world_mut();
            if on_head {
                world.spawn((collider, transform, HairColliderOf(head), ChildOf(head)));
            } else {
                world.spawn((
                    collider,
                    transform.with_translation(head_position + transform.translation),
                    HairColliderOf(head),
                ));
            }
        }
        self
    }

    /// The scene with `collider` on the head, at `transform` from it.
    pub fn with_collider(mut self, collider: HairCollider, transform: Transform) -> Self {
        let head = self.head;
        self.app.world_mut().spawn((collider, transform, HairColliderOf(head), ChildOf(head)));
        self
    }

    /// The head's position and orientation at step `step`: a sway of 5 cm and a turn of ±0.4 rad, about
    /// once a second, at 1.6 m.
    pub fn head_pose(step: usize) -> (Vec3, Quat) {
        let time = step as f32 / 60.0;
        let sway = 0.05 * (std::f32::consts::TAU * 0.8 * time).sin();
        (Vec3::new(sway, 1.6, 0.0), Quat::from_rotation_y(0.4 * (std::f32::consts::TAU * 0.5 * time).sin()))
    }

    /// Moves the head to [`Scene::head_pose`] and runs one step.
    pub fn step(&mut self) {
        self.step += 1;
        let (translation, rotation) = Self::head_pose(self.step);
        let mut head = self.app.world_mut().get_mut::<Transform>(self.head).expect("the head exists");
        (head.translation, head.rotation) = (translation, rotation);
        self.app.update();
    }

    /// Runs the warm-up steps.
    pub fn warm_up(&mut self) {
        for _ in 0..WARM_UP_STEPS {
            self.step();
        }
    }
}

/// A crowd: `heads` heads of the scene's hair, each swaying and turning as [`Scene::head_pose`] with its own
/// phase, around one camera. The camera looks at the first two heads from 1.2 m; the others stand 4 to
/// 11 m away from it, the first `in_view` of them ahead (at 4, 5, 6, 7 m, … within 20° of its axis) and
/// the rest behind it or to its sides, out of its view.
pub struct Crowd {
    pub app: App,
    pub heads: Vec<(Entity, Vec3)>,
    step: usize,
}

impl Crowd {
    /// The crowd with levels of detail chosen from the camera (`detail`), or every head at full detail.
    pub fn new(
        heads: usize,
        in_view: usize,
        strands: usize,
        edges: usize,
        threads: Option<usize>,
        detail: bool,
    ) -> Self {
        use bevy::camera::primitives::Frustum;
        use bevy::camera::{CameraProjection, PerspectiveProjection};
        use bevy::math::primitives::ViewFrustum;

        let mut app = Scene::app(threads);
        app.world_mut().resource_mut::<HairDetailSettings>().enabled = detail;
        let camera = Transform::from_xyz(0.0, 1.6, 1.2).looking_at(Vec3::new(0.0, 1.55, 0.0), Vec3::Y);
        let projection = PerspectiveProjection { aspect_ratio: 16.0 / 9.0, ..default() };
        let clip_from_world = projection.get_clip_from_view() * camera.to_matrix().inverse();
        let frustum = Frustum(ViewFrustum::from_clip_from_world(&clip_from_world));
        app.world_mut().spawn((Camera::default(), camera, GlobalTransform::from(camera), frustum));
        let roots = Scalp::default().roots(strands).expect("the default scalp holds any count");
        let heads = (0..heads)
            .map(|index| {
                let base = match index {
                    0 => Vec3::new(-0.2, 1.6, 0.0),
                    1 => Vec3::new(0.2, 1.6, 0.0),
                    _ => {
                        const AHEAD: [f32; 4] = [-20.0, 20.0, -10.0, 10.0];
                        const AWAY: [f32; 8] = [100.0, 160.0, -160.0, -100.0, 130.0, -130.0, 180.0, 70.0];
                        let other = index - 2;
                        let degrees = if other < in_view { AHEAD[other % 4] } else { AWAY[(other - in_view) % 8] };
                        let angle = degrees.to_radians();
                        let distance = 2.0 + index as f32;
                        Vec3::new(distance * angle.sin(), 1.6, 1.2 - distance * angle.cos())
                    }
                };
                let head = app
                    .world_mut()
                    .spawn((HairHead, Transform::from_translation(base)))
                    .with_related_entities::<StrandOf>(|head| {
                        for root in &roots {
                            head.spawn(HairStrand::straight(root.position, root.normal, HAIR_LENGTH, edges));
                        }
                    })
                    .id();
                (head, base)
            })
            .collect();
        Self { app, heads, step: 0 }
    }

    /// Moves every head (each 7 steps of the motion apart) and runs one step.
    pub fn step(&mut self) {
        self.step += 1;
        for (index, &(head, base)) in self.heads.iter().enumerate() {
            let (translation, rotation) = Scene::head_pose(self.step + 7 * index);
            let mut transform = self.app.world_mut().get_mut::<Transform>(head).expect("the head exists");
            (transform.translation, transform.rotation) = (base + translation - Vec3::new(0.0, 1.6, 0.0), rotation);
        }
        self.app.update();
    }

    /// How many heads are at each level of detail after the last step.
    pub fn levels(&self) -> HeadsByDetail {
        self.app.world().resource::<HairStatistics>().heads_by_detail
    }
}
