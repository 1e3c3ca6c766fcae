//! No heap allocation per step once running: a counting global allocator watches the mechanics core's
//! step (none at all), and a whole app's update (what Bevy itself allocates per frame, the same however
//! many strands there are, so the hair adds none). A binary of its own: the count is the whole process's.

use std::sync::atomic::Ordering;

use bevy::math::{DQuat, DVec3};
use bevy::prelude::*;
use bevy::tasks::{ComputeTaskPool, TaskPoolBuilder};
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::{Rod, RodWorkspace, StepParams};
use hair_sim_support::counting_allocator::{ALLOCATIONS, CountingAllocator, thread_allocations};
use hair_sim_support::headless::hair_app;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// Allocations made by all threads so far.
fn all_threads() -> u64 {
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// How much `count` (allocations so far: [`all_threads`], or `thread_allocations` for this thread
/// alone, blind to the harness's main thread, which allocates now and then while a test runs) grows
/// while `work` runs.
fn allocations_during(count: fn() -> u64, work: impl FnOnce()) -> u64 {
    let before = count();
    work();
    count() - before
}

/// Allocations per update of an app with one head of `strands` strands (32 edges, 4 followers each) that
/// moves, with colliders, in a gusty, turbulent wind with a fan, with hair–hair interaction (smoothing and
/// pressure) and the style held, at the level of detail `level`, once running.
fn allocations_per_update(strands: usize, level: HairDetailLevel) -> u64 {
    let mut app = hair_app();
    let mut settings = app.world_mut().resource_mut::<HairSettings>();
    (settings.volume.enabled, settings.volume.stiffness) = (true, 50.0);
    settings.style_hold = HairStyleHold { rate: 200.0, ..default() };
    app.insert_resource(HairWind { velocity: Vec3::new(2.0, 0.0, 0.0), gusts: 1.0, turbulence: 0.5, ..default() });
    app.world_mut().spawn((
        HairWindSource { speed: 4.0, radius: 0.05, range: 1.0 },
        Transform::from_xyz(0.0, 1.6, 0.5).looking_at(Vec3::new(0.0, 1.6, 0.0), Vec3::Y),
    ));
    let groom = HairGroom { strand_count: strands, segments: 32, followers_per_guide: 4, ..default() };
    let head =
        app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0), groom, HairDetail::fixed(level))).id();
    // The skull, on the head, and a shared floor that the hair does not reach.
    app.world_mut().spawn((HairCollider::sphere(0.1), HairColliderOf(head), ChildOf(head)));
    app.world_mut().spawn(HairCollider::plane());
    let mut step = 0;
    let mut run = |app: &mut App, updates: usize| {
        for _ in 0..updates {
            step += 1;
            app.world_mut().get_mut::<Transform>(head).unwrap().rotation = Quat::from_rotation_y(0.02 * step as f32);
            app.update();
        }
    };
    run(&mut app, 30);
    let updates = 30;
    allocations_during(all_threads, || run(&mut app, updates)) / updates as u64
}

/// Allocations per frame of preparing a head of `strands` strands (4 followers each) for the renderer
/// (checking the layout, writing the interpolated positions) on `threads` threads, once laid out; counted
/// on all threads, or on this one with `count`.
fn allocations_per_drawn_frame(strands: usize, threads: usize, count: fn() -> u64) -> f64 {
    use bevy_hair_sim::render::{GuideLayout, HairStrips};
    let mut app = hair_app();
    let groom = HairGroom { strand_count: strands, segments: 16, followers_per_guide: 4, ..default() };
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0), groom)).id();
    for _ in 0..3 {
        app.update();
    }
    let world = app.world();
    let guides = world.get::<HeadStrands>(head).unwrap().strands();
    let layout = || {
        guides.iter().filter_map(|&entity| {
            let nodes = world.get::<StrandNodes>(entity)?;
            Some(GuideLayout::new(entity, nodes, world.get::<FollowerNodes>(entity), 4e-5))
        })
    };
    let lookup = |entity| Some((world.get::<StrandNodes>(entity)?, world.get::<FollowerNodes>(entity)));
    let mut strips = HairStrips::default();
    strips.set_layout(layout());
    strips.fill(0.5, threads, lookup);
    let frames = 50;
    allocations_during(count, || {
        for frame in 0..frames {
            assert!(!strips.set_layout(layout()));
            assert!(strips.fill(frame as f32 / frames as f32, threads, lookup).is_some());
        }
    }) as f64
        / frames as f64
}

// One test, so that no other test allocates while it counts.
#[test]
fn stepping_allocates_nothing_once_running() {
    // One compute thread on any machine (as Bevy gives a machine of two cores; the test apps ask for every
    // core, but the first to make the pool sets it): how Bevy's executor splits the work, and what it
    // allocates for that, depends on the threads sharing it.
    ComputeTaskPool::get_or_init(|| TaskPoolBuilder::new().num_threads(1).build());
    // The core: a hair whose root is shaken and spun, with its workspace warmed up by one step.
    let nodes: Vec<DVec3> = (0..=32).map(|i| DVec3::new(0.25 * i as f64 / 32.0, 0.0, 0.0)).collect();
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
    rod.clamp_root_in_place();
    let root = [rod.positions()[0], rod.positions()[1]];
    let params = StepParams::default();
    let mut workspace = RodWorkspace::default();
    rod.step(&params, None, &mut workspace).unwrap();
    let core = allocations_during(thread_allocations, || {
        for step in 1..=200 {
            let time = step as f64 * params.dt;
            let turn = DQuat::from_rotation_y(4.0 * std::f64::consts::PI * time);
            let shift = DVec3::new(0.1 * (20.0 * time).sin(), 0.0, 0.0);
            rod.clamp_edge(0, turn * root[0] + shift, turn * root[1] + shift, turn * DVec3::Y).unwrap();
            rod.step(&params, None, &mut workspace).unwrap();
        }
    });
    assert_eq!(core, 0, "the core's step allocated {core} times in 200 steps");

    // The plugin: Bevy allocates a little every frame (its executor, its task scopes); the hair adds
    // nothing to that, however many strands there are.
    for level in [HairDetailLevel::FULL, HairDetailLevel::Stepped(4), HairDetailLevel::Carried] {
        let few = allocations_per_update(50, level);
        let many = allocations_per_update(400, level);
        println!("allocations per update at {level:?}: {few} with 50 strands, {many} with 400");
        assert_eq!(
            few, many,
            "allocations per update at {level:?} grow with the strands: {few} with 50, {many} with 400"
        );
    }

    // Preparing hair for the renderer: nothing on one thread; on two, only the task scope's, the same
    // however many strands.
    let single = allocations_per_drawn_frame(400, 1, thread_allocations);
    assert_eq!(single, 0.0, "preparing hair for drawing allocated {single} times per frame");
    // The task scope's allocations on two threads vary by a few in 50 frames with how the threads are
    // scheduled (11.26 in one run; whole numbers made 11.02 and 10.98 read as 11 and 10); one per strand
    // would add 350 per frame.
    let few = allocations_per_drawn_frame(50, 2, all_threads);
    let many = allocations_per_drawn_frame(400, 2, all_threads);
    println!("allocations per drawn frame on two threads: {few} with 50 strands, {many} with 400");
    assert!(
        (many - few).abs() < 1.0,
        "allocations per drawn frame grow with the strands: {few} with 50, {many} with 400"
    );
}
