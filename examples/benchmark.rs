//! Prints how fast the hair simulation runs: `cargo run --release --example benchmark`.
//!
//! The real plugin in a headless app (see `support/src/bench_scene.rs`): 25 cm human hairs on a swaying,
//! turning head, gravity on, dt = 1/60 s. A row's time is the median wall time of the measured steps
//! (the whole fixed step: pinning roots, stepping strands, writing poses), after the hair has fallen and
//! started to swing.
//!
//! Arguments: the tables to print (`scaling`, `parts`, `collisions`, `parallel`, `memory`, `preload`,
//! `lockstep`, `mesh-collider`, `followers`, `integrators`, `volume`, `render`, `crowd`, `coverage`,
//! `bare`, `hold`, `scene`, `budget`, `styles`; all by default), `--quick` to measure fewer steps, `--threads N` for the
//! compute threads (one per core by default), `--style NAME` to measure one style in `styles`,
//! `--motion NAME` one motion (`rest`, `shake`, `turn`, `flick`) in `coverage`, `--air-damping G` the air's
//! drag (1/s, `HairSettings::air_damping`) in `coverage` instead of the default, `--gpu` the `coverage`
//! runs stepped on the GPU (Bevy's renderer on whatever adapter wgpu finds), `--budget MS` a CPU budget
//! (`HairCpuBudget`) in `coverage` and `styles`, `--setting NAME` one row's setting in `budget` (`none`,
//! `4`, `2`, `every-2`, `every-4`, `every-8`, `every-16`, `carried`; with `--motion still|shaken`, one row
//! to profile), `--guides N` the example's 22 000 hairs grown from `N`
//! guides instead of 2 000 in `coverage`, `styles`, `scene` and `budget`. Bevy's task pools are set
//! once per process, so the parallel table runs this program again with `--threads`.

use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use bevy::math::{DVec3, Vec2, Vec3};
use bevy::tasks::available_parallelism;
use bevy_hair_sim::detail::HeadsByDetail;
use bevy_hair_sim::groom::ScalpRoot;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::{
    ColliderShape, Contacts, Integrator, LANES, LockstepStrand, LockstepWorkspace, MovingCollider, RigidPose, Rod,
    RodWorkspace, StepLoads, StepParams, StepTimings,
};
use bevy_hair_sim::simulation::SimulatedStrand;
use bevy_hair_sim::volume::RepresentedHairs;
use hair_sim_support::bench_scene::{Crowd, HAIR_LENGTH, Scene, WARM_UP_STEPS};
use hair_sim_support::counting_allocator::{BYTES_IN_USE, CountingAllocator};
use hair_sim_support::example_scene;

/// Counting the bytes in use, for the memory per node.
#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// Median wall time of `steps` steps, s, after the warm-up, with `colliders` colliders.
fn median_step_seconds(strands: usize, edges: usize, colliders: usize, threads: usize, steps: usize) -> f64 {
    let mut scene = Scene::new(strands, edges, Some(threads)).with_colliders(colliders);
    scene.warm_up();
    let mut times: Vec<f64> = (0..steps)
        .map(|_| {
            let started = Instant::now();
            scene.step();
            started.elapsed().as_secs_f64()
        })
        .collect();
    median(&mut times)
}

/// The median of `times` (sorted in place); `times` must not be empty.
fn median(times: &mut [f64]) -> f64 {
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

/// Median wall time per step of each scene, s, after the warm-up, stepping them in turn so that the
/// machine's slow drifts fall on all alike.
fn interleaved_median_step_seconds(scenes: &mut [Scene], steps: usize) -> Vec<f64> {
    scenes.iter_mut().for_each(Scene::warm_up);
    let mut times = vec![Vec::with_capacity(steps); scenes.len()];
    for _ in 0..steps {
        for (scene, times) in scenes.iter_mut().zip(&mut times) {
            let started = Instant::now();
            scene.step();
            times.push(started.elapsed().as_secs_f64());
        }
    }
    times.iter_mut().map(|times| median(times)).collect()
}

/// The value following `flag` in `args`, parsed.
fn flag_value(args: &[String], flag: &str) -> Option<usize> {
    let position = args.iter().position(|arg| arg == flag)?;
    let value = args.get(position + 1)?;
    Some(value.parse().unwrap_or_else(|_| panic!("{flag} needs a number, got {value:?}")))
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|arg| arg == "--quick");
    let steps = if quick { 15 } else { 60 };
    let cores = available_parallelism();
    let threads = flag_value(&args, "--threads").unwrap_or(cores);
    if args.first().is_some_and(|arg| arg == "measure") {
        let number = |index: usize| args.get(index).and_then(|arg| arg.parse().ok());
        let (strands, edges) = number(1).zip(number(2)).expect("measure STRANDS EDGES [COLLIDERS]");
        let colliders = number(3).unwrap_or(0);
        println!("{}", median_step_seconds(strands, edges, colliders, threads, steps));
        return;
    }
    let tables: Vec<&str> = args
        .iter()
        .enumerate()
        .filter(|&(index, arg)| {
            !arg.starts_with("--")
                && (index == 0
                    || !["--threads", "--style", "--motion", "--air-damping", "--budget", "--guides", "--setting"]
                        .contains(&args[index - 1].as_str()))
        })
        .map(|(_, arg)| arg.as_str())
        .collect();
    let wanted = |table: &str| tables.is_empty() || tables.contains(&table);
    let budget = args
        .iter()
        .position(|arg| arg == "--budget")
        .and_then(|position| args.get(position + 1))
        .map(|value| value.parse::<f32>().expect("--budget needs milliseconds"));
    if let Some(guides) = flag_value(&args, "--guides") {
        GUIDES.store(guides.max(1), Ordering::Relaxed);
    }
    println!("bevy_hair_sim benchmark: {cores} cores, {threads} compute threads, {steps} measured steps per row");
    if wanted("scaling") {
        scaling(threads, steps);
    }
    if wanted("parts") {
        parts_of_a_step(if quick { 100 } else { 600 });
    }
    if wanted("lockstep") {
        lockstep(threads, steps);
    }
    if wanted("collisions") {
        collisions(threads, steps);
    }
    if wanted("parallel") {
        parallel_efficiency(cores, quick);
    }
    if wanted("memory") {
        memory_per_node(threads);
    }
    if wanted("preload") {
        preload_cost();
    }
    if wanted("mesh-collider") {
        mesh_collider_cost(threads, steps);
    }
    if wanted("followers") {
        followers_cost(threads, steps);
    }
    if wanted("integrators") {
        integrators(threads, steps);
    }
    if wanted("volume") {
        volume_cost(threads, steps);
    }
    if wanted("render") {
        render_preparation(threads, if quick { 50 } else { 400 });
        followers_on_the_gpu(threads, if quick { 30 } else { 200 });
    }
    if wanted("crowd") {
        crowd(threads, steps);
    }
    if wanted("coverage") {
        let value = |flag: &str| args.iter().position(|arg| arg == flag).and_then(|position| args.get(position + 1));
        let air_damping = value("--air-damping").map(|value| value.parse::<f32>().expect("--air-damping needs 1/s"));
        let on_gpu = args.iter().any(|arg| arg == "--gpu");
        let seconds = if quick { 1.0 } else { 4.0 };
        coverage(threads, seconds, value("--motion").map(String::as_str), air_damping, budget, on_gpu);
    }
    if wanted("bare") {
        bare_regions(threads, if quick { 1.0 } else { 4.0 });
    }
    if wanted("hold") {
        hold_cost(threads, if quick { 60 } else { 240 });
    }
    if wanted("scene") {
        example_scene_cost(threads, if quick { 60 } else { 240 });
    }
    if wanted("budget") {
        let setting = args.iter().position(|arg| arg == "--setting").and_then(|position| args.get(position + 1));
        let motion = args.iter().position(|arg| arg == "--motion").and_then(|position| args.get(position + 1));
        budgeted_scene_cost(
            threads,
            if quick { 60 } else { 240 },
            setting.map(String::as_str),
            motion.map(String::as_str),
        );
    }
    if wanted("styles") {
        let style = args.iter().position(|arg| arg == "--style").and_then(|position| args.get(position + 1));
        let styles: Vec<HairStyle> =
            HairStyle::ALL.into_iter().filter(|style_| style.is_none_or(|name| style_.name() == name)).collect();
        styles_at_rest(threads, if quick { 1.0 } else { 3.0 }, &styles, budget);
    }
    #[cfg(feature = "gpu")]
    if wanted("gpu") {
        let largest = if quick { 10_000 } else { 50_000 };
        gpu::steps_on_the_gpu(threads, if quick { 10 } else { 40 }, largest);
        gpu::plugin_cpu_cost(if quick { 30 } else { 120 });
    }
}

/// The `gpu` table: the strand step on the GPU and the followers placed and drawn from it there.
#[cfg(feature = "gpu")]
mod gpu {
    use std::time::Instant;

    use bevy::prelude::Entity;
    use bevy_hair_sim::gpu::{
        GpuHeadStep, GpuStrandInput, GpuStrandSolver, GpuStrandWork, bind_whole_buffers, compute_layout,
        compute_pipeline, headless_device,
    };
    use bevy_hair_sim::prelude::*;
    use bevy_hair_sim::render::feed::{GpuCollider, GuideUpload};
    use bevy_hair_sim::render::{DrawnStrand, GuideLayout, HairStrips};
    use bevy_hair_sim::rod::{MovingCollider, RigidPose};
    use bevy_hair_sim::simulation::SimulatedStrand;
    use wgpu::util::DeviceExt;

    use super::{Scene, WARM_UP_STEPS, groomed_head, move_head};

    /// How long a row of the table steps before it stops short of its steps, s.
    const ROW_SECONDS: f64 = 20.0;

    /// The follower placement's shader, as the renderer loads it.
    const FOLLOWERS_SHADER: &str = include_str!("../src/render/followers.wgsl");

    /// GPU time per step (timestamp queries where the adapter has them, otherwise from submit to done) of
    /// the strand step for a groom of 2 000 guides × 32 edges with 10 followers each (20 000), and of the
    /// followers' part (the guides gathered from the step's buffers, the followers placed in their frames
    /// and pushed out of the skull, every drawn node written for the frame), and of 10 000 guides × 32 edges
    /// and 50 000 (up to `largest` guides) without followers. The guides come from the plugin's groom, moved
    /// as the other tables move their head; `steps` steps per row after two untimed ones (fewer, three at
    /// least, once the row has run `ROW_SECONDS`). Each row also
    /// prints the work the shader counted per strand-step (Newton iterations, projection iterations,
    /// contact rounds; the busiest strand's projection iterations, which its warp waits for) and the bytes
    /// a step moves: uploaded (parameters, the head's pose and colliders) and, where read back, read back.
    pub fn steps_on_the_gpu(threads: usize, steps: usize, largest: usize) {
        let (device, queue, info) = match headless_device() {
            Ok(found) => found,
            Err(error) => {
                println!("\nGPU: no adapter ({error}); nothing to measure");
                return;
            }
        };
        let timestamps = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        println!(
            "\nGPU: {} ({:?}, {:?}, {}); time per step {}",
            info.name,
            info.device_type,
            info.backend,
            info.driver_info,
            if timestamps { "from timestamp queries" } else { "from submit to done (no timestamp queries)" }
        );
        println!(
            "{:>8} {:>6} {:>10} {:>10} {:>13} {:>9} {:>7} {:>9} {:>8} {:>9} {:>8} {:>12}",
            "guides",
            "edges",
            "followers",
            "step ms",
            "followers ms",
            "total ms",
            "Newton",
            "project",
            "contact",
            "busiest",
            "up B",
            "read-back B"
        );
        for (guides, followers) in [(2_000, 10), (10_000, 0), (50_000, 0)] {
            if guides > largest {
                continue;
            }
            let row = Row::new(&device, threads, guides, followers);
            let read_back_bytes = row.solver.read_back_bytes(true);
            let (measured, work) = row.measure(&device, &queue, timestamps, steps);
            let [step, placed] = measured;
            let total = GpuStrandWork::total(&work);
            let [newton, projection, _, _, _, rounds, _] = total.per_step();
            let busiest = work.iter().map(|w| f64::from(w.projection_iterations) / f64::from(w.steps.max(1)));
            let busiest = busiest.fold(0.0, f64::max);
            // Per step the CPU writes the parameters (80 B), the head's five rows and its collider's five.
            let uploaded = 80 + 2 * 5 * 16;
            println!(
                "{guides:>8} {:>6} {:>10} {:>10.3} {:>13.3} {:>9.3} {newton:>7.2} {projection:>9.2} {rounds:>8.2} \
                 {busiest:>9.2} {uploaded:>8} {read_back_bytes:>12}",
                32,
                guides * followers,
                1e3 * step,
                1e3 * placed,
                1e3 * (step + placed)
            );
        }
        println!(
            "(Newton, project, contact: per strand-step, averaged over every strand; busiest: the projection \
             iterations per step of the strand that took most. read-back B: bytes of one read-back, when asked)"
        );
    }

    /// A headless app with Bevy's renderer on whatever adapter wgpu finds (no window, the render world in
    /// the app's update), the hair plugins (the GPU stepping the hair), `threads` compute threads (`None`:
    /// Bevy's default), one fixed step of 1/60 s per update, its plugins finished.
    pub fn rendered_app(threads: Option<usize>) -> bevy::prelude::App {
        use bevy::app::PluginsState;
        use bevy::prelude::*;
        use bevy::render::pipelined_rendering::PipelinedRenderingPlugin;
        use bevy::time::TimeUpdateStrategy;
        use bevy::window::ExitCondition;
        let mut app = App::new();
        let mut plugins = DefaultPlugins
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                close_when_requested: false,
                ..default()
            })
            .disable::<PipelinedRenderingPlugin>();
        if let Some(threads) = threads {
            let task_pool_options = HairPlugins::task_pool_options_with_threads(threads);
            plugins = plugins.set(TaskPoolPlugin { task_pool_options });
        }
        // Built with the examples' window, the app still has none (and needs no display).
        #[cfg(feature = "examples")]
        let plugins = plugins.disable::<bevy::winit::WinitPlugin>();
        app.add_plugins((plugins, HairPlugins::default()));
        app.insert_resource(Time::<Fixed>::from_seconds(1.0 / 60.0))
            .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
        while app.plugins_state() == PluginsState::Adding {
            bevy::tasks::tick_global_task_pools_on_main_thread();
        }
        app.finish();
        app.cleanup();
        app
    }

    /// The plugin's CPU time per fixed step with the GPU stepping 2 000 guides × 32 edges with 10 followers
    /// each on the skull, in a headless app with Bevy's renderer: the main world's systems and the render
    /// world's (`HairGpuStatus::main_thread_seconds`, `render_thread_seconds`), with the components read
    /// back after every step and never, interleaved step by step over two apps. Before each step the GPU's
    /// queue is drained, so that a software adapter (lavapipe runs the shader on the CPU's cores) does not
    /// compete with the plugin's own work for the cores, as a GPU would not.
    pub fn plugin_cpu_cost(steps: usize) {
        use bevy::prelude::*;
        let app = |read_back: GpuReadBackRate| {
            let mut app = rendered_app(None);
            app.insert_resource(HairGpuSettings { read_back, ..default() });
            let groom = HairGroom { strand_count: 2_000, followers_per_guide: 10, segments: 32, ..default() };
            let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
            app.world_mut().spawn((
                HairCollider::sphere(0.1),
                HairColliderOf(head),
                ChildOf(head),
                Transform::default(),
            ));
            (app, head)
        };
        let mut apps = [app(GpuReadBackRate::EveryStep), app(GpuReadBackRate::OnDemand)];
        // Until the groom is built, preloaded and on the GPU.
        for _ in 0..600 {
            for (app, _) in &mut apps {
                app.update();
            }
            // On the GPU, and stepped there a few times (the first upload builds the pipelines).
            if apps.iter().all(|(app, _)| {
                let status = app.world().resource::<HairGpuStatus>();
                status.strands == 2_000 && status.steps > 3 && status.render_thread_seconds > 0.0
            }) {
                break;
            }
        }
        let mut seconds = [[0.0; 3]; 2];
        for step in 0..steps {
            for (index, (app, head)) in apps.iter_mut().enumerate() {
                let t = step as f32 / 60.0;
                app.world_mut().get_mut::<Transform>(*head).unwrap().rotation =
                    Quat::from_rotation_y(0.7 * (6.0 * t).sin());
                if let Some(render) = app.get_sub_app(bevy::render::RenderApp) {
                    let device = render.world().resource::<bevy::render::renderer::RenderDevice>();
                    let _ = device.wgpu_device().poll(wgpu::PollType::wait_indefinitely());
                }
                app.update();
                let status = app.world().resource::<HairGpuStatus>();
                seconds[index][0] += status.main_thread_seconds;
                seconds[index][1] += status.render_thread_seconds - status.render_driver_seconds;
                seconds[index][2] += status.render_driver_seconds;
            }
        }
        let strands = apps[0].0.world().resource::<HairGpuStatus>().strands;
        println!(
            "\nThe plugin's CPU time per step, {strands} guides × 32 edges on the GPU, 20 000 followers, {steps} steps"
        );
        println!(
            "{:>22} {:>12} {:>14} {:>10} {:>30}",
            "read-back", "main ms", "render ms", "total ms", "in wgpu's submit and poll ms"
        );
        for (index, name) in ["every step", "off (on demand)"].into_iter().enumerate() {
            let [main, render, driver] = seconds[index].map(|s| 1e3 * s / steps as f64);
            println!("{name:>22} {main:>12.3} {render:>14.3} {:>10.3} {driver:>30.3}", main + render);
        }
        println!(
            "(the GPU idle before each step; render ms leaves out wgpu's submit and poll, which on a software \
             adapter run the GPU's work itself; on a GPU they return at once)"
        );
    }

    /// One row's guides on the GPU, with its followers' buffers and pipelines when it has followers.
    struct Row {
        solver: GpuStrandSolver,
        followers: Option<Followers>,
        skull: MovingCollider,
    }

    /// The follower placement's buffers and pipelines (as `render/followers.rs` makes them in the renderer).
    struct Followers {
        target: bevy_hair_sim::gpu::GpuGatherTarget,
        guides_offset: u32,
        place: wgpu::ComputePipeline,
        draw: wgpu::ComputePipeline,
        place_group: wgpu::BindGroup,
        draw_group: wgpu::BindGroup,
        drawn_nodes: u32,
    }

    impl Row {
        fn new(device: &wgpu::Device, threads: usize, guides: usize, followers: usize) -> Self {
            let (mut app, head) = groomed_head(threads, guides, followers, 32);
            // The skull under the scalp, which the CPU meets in the warm-up as the GPU does after it.
            app.world_mut().spawn((
                HairCollider::sphere(0.1),
                HairColliderOf(head),
                bevy::prelude::ChildOf(head),
                bevy::prelude::Transform::default(),
            ));
            for step in 1..=WARM_UP_STEPS {
                move_head(&mut app, head, step);
            }
            let strands: Vec<Entity> = app.world().get::<HeadStrands>(head).expect("a groom").strands().to_vec();
            let margin = HairSettings::default().collision_margin;
            let world = app.world();
            let inputs: Vec<GpuStrandInput> = strands
                .iter()
                .map(|&strand| {
                    let simulated = world.get::<SimulatedStrand>(strand).expect("built");
                    let thickness = f64::from(simulated.collision_thickness(margin));
                    GpuStrandInput {
                        rod: simulated.rod(),
                        head: 0,
                        thickness,
                        groomed: None,
                        hairs: 1.0,
                        groomed_fractions: None,
                    }
                })
                .collect();
            let (translation, rotation) = Scene::head_pose(WARM_UP_STEPS);
            let pose = (rotation.as_dquat(), translation.as_dvec3());
            let solver = GpuStrandSolver::new(device, &inputs, &[pose]).expect("strands the GPU takes");
            // The skull under the groom's scalp (a sphere of 10 cm about the head's origin).
            let at = RigidPose { rotation: pose.0, translation: pose.1 };
            let skull = MovingCollider {
                shape: bevy_hair_sim::rod::ColliderShape::Sphere { radius: 0.1 },
                friction: 0.3,
                start: at,
                end: at,
            };
            let followers = (followers > 0).then(|| {
                let mut drawn = app.world_mut().query::<DrawnStrand>();
                let query = drawn.query(app.world());
                let layout = |entity| {
                    let (strand, nodes, followers, represented, ..) = query.get(entity).ok()?;
                    Some((GuideLayout::drawn(entity, strand, nodes, followers, represented), followers))
                };
                let mut strips = HairStrips::default();
                strips.set_layout(strands.iter().filter_map(|&entity| Some(layout(entity)?.0)));
                let mut upload = GuideUpload::default();
                upload.set_layout(strands.iter().filter_map(|&entity| layout(entity)));
                Followers::new(device, &solver, &upload, &skull)
            });
            Self { solver, followers, skull }
        }

        /// Seconds per step (the strand step, and the followers' part), and each strand's work.
        fn measure(
            mut self,
            device: &wgpu::Device,
            queue: &wgpu::Queue,
            timestamps: bool,
            steps: usize,
        ) -> ([f64; 2], Vec<GpuStrandWork>) {
            let params = bevy_hair_sim::rod::StepParams::default();
            let queries = timestamps.then(|| {
                device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("hair benchmark"),
                    ty: wgpu::QueryType::Timestamp,
                    count: 3 * steps as u32,
                })
            });
            let mut wall = [0.0; 2];
            // Steps timed: `steps`, or fewer (three at least) once a row has run `ROW_SECONDS` (a software
            // adapter takes seconds a step).
            let mut taken = 0;
            let row_started = Instant::now();
            for step in 0..steps + 2 {
                if taken >= 3 && row_started.elapsed().as_secs_f64() > ROW_SECONDS {
                    break;
                }
                let (translation, rotation) = Scene::head_pose(WARM_UP_STEPS + 1 + step);
                let mut head = GpuHeadStep {
                    rotation: rotation.as_dquat(),
                    translation: translation.as_dvec3(),
                    ..GpuHeadStep::default()
                };
                let at = RigidPose { rotation: head.rotation, translation: head.translation };
                self.skull.start = self.skull.end;
                self.skull.end = at;
                head.colliders.push(self.skull.clone());
                let timed = step >= 2;
                let mark = |encoder: &mut wgpu::CommandEncoder, index: usize| {
                    if let (Some(queries), true) = (&queries, timed) {
                        let index = (3 * (step - 2) + index) as u32;
                        let writes = wgpu::ComputePassTimestampWrites {
                            query_set: queries,
                            beginning_of_pass_write_index: Some(index),
                            end_of_pass_write_index: None,
                        };
                        drop(encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                            label: Some("hair benchmark mark"),
                            timestamp_writes: Some(writes),
                        }));
                    }
                };
                // The step, then (in a submission of its own, for the wall clock) the followers' part.
                let started = Instant::now();
                let mut encoder = device.create_command_encoder(&Default::default());
                mark(&mut encoder, 0);
                self.solver.record_step(device, queue, &mut encoder, &params, &[head]).expect("a valid step");
                mark(&mut encoder, 1);
                queue.submit([encoder.finish()]);
                let _ = device.poll(wgpu::PollType::wait_indefinitely());
                let stepped = Instant::now();
                if let Some(followers) = &self.followers {
                    let mut encoder = device.create_command_encoder(&Default::default());
                    followers.record(&self.solver, queue, &mut encoder);
                    mark(&mut encoder, 2);
                    queue.submit([encoder.finish()]);
                    let _ = device.poll(wgpu::PollType::wait_indefinitely());
                } else {
                    let mut encoder = device.create_command_encoder(&Default::default());
                    mark(&mut encoder, 2);
                    queue.submit([encoder.finish()]);
                }
                if timed {
                    taken += 1;
                    wall[0] += (stepped - started).as_secs_f64();
                    if self.followers.is_some() {
                        wall[1] += stepped.elapsed().as_secs_f64();
                    }
                }
            }
            let states = self.solver.read_back(device, queue);
            let faults: u32 = states.status.iter().map(|s| s.faults).sum();
            if faults > 0 {
                let first = states.status.iter().position(|s| s.faults > 0).unwrap();
                println!("{faults} faults; first strand {first}: {:?}", states.status[first]);
            }
            let work = self.solver.read_work(device, queue);
            let Some(queries) = queries else {
                return (wall.map(|seconds| seconds / taken as f64), work);
            };
            let count = 3 * taken as u64;
            let resolved = device.create_buffer(&wgpu::BufferDescriptor {
                label: None,
                size: 8 * count,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = device.create_buffer(&wgpu::BufferDescriptor {
                label: None,
                size: 8 * count,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut encoder = device.create_command_encoder(&Default::default());
            encoder.resolve_query_set(&queries, 0..count as u32, &resolved, 0);
            encoder.copy_buffer_to_buffer(&resolved, 0, &read, 0, 8 * count);
            queue.submit([encoder.finish()]);
            read.slice(..).map_async(wgpu::MapMode::Read, |_| {});
            let _ = device.poll(wgpu::PollType::wait_indefinitely());
            let ticks: Vec<u64> = bytemuck::cast_slice(&read.slice(..).get_mapped_range()).to_vec();
            let period = f64::from(queue.get_timestamp_period()) * 1e-9;
            let mut gpu = [0.0; 2];
            for step in ticks.chunks_exact(3) {
                gpu[0] += step[1].saturating_sub(step[0]) as f64 * period;
                gpu[1] += step[2].saturating_sub(step[1]) as f64 * period;
            }
            if self.followers.is_none() {
                gpu[1] = 0.0;
            }
            (gpu.map(|seconds| seconds / taken as f64), work)
        }
    }

    impl Followers {
        fn new(device: &wgpu::Device, solver: &GpuStrandSolver, upload: &GuideUpload, skull: &MovingCollider) -> Self {
            let guide_nodes = upload.guide_node_count() as u32;
            let starts = upload.guide_starts();
            let guides = starts.len() as u32 - 1;
            // As `render/followers.rs` lays a step's data out: positions, frame codes (unused here: the
            // gather writes the frames), the guide words.
            let guides_offset = 3 * guide_nodes + (3 * guide_nodes).div_ceil(4);
            let storage = |size: u64| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: None,
                    size: size.max(16),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            let with_data = |contents: &[u8]| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: None,
                    contents,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::UNIFORM,
                })
            };
            let drawn_nodes = upload.drawn_node_count() as u32;
            let guide_data = storage(4 * u64::from(guides_offset + 2 * guides));
            let guide_frames = storage(16 * u64::from(guide_nodes));
            let map: Vec<[u32; 2]> = starts
                .iter()
                .enumerate()
                .map(|(guide, &first)| [guide.min(guides as usize - 1) as u32, first])
                .collect();
            let target = solver.gather_target(device, &map, &guide_data, &guide_frames);
            let params: [u32; 8] =
                [drawn_nodes, guide_nodes, guides, 1, 3 * guide_nodes, guides_offset, 0.5_f32.to_bits(), 0];
            let params = with_data(bytemuck::cast_slice(&params));
            let nodes = with_data(bytemuck::cast_slice(&upload.drawn_nodes));
            let guide_of_node = with_data(bytemuck::cast_slice(&upload.guide_of_node));
            let guide_starts = with_data(bytemuck::cast_slice(&starts));
            let colliders = with_data(bytemuck::cast_slice(&[GpuCollider::new(skull).expect("a sphere")]));
            let placed = [storage(12 * u64::from(drawn_nodes)), storage(12 * u64::from(drawn_nodes))];
            let drawn = storage(12 * u64::from(drawn_nodes));
            // The layouts of `render/followers.rs`: a uniform, then storage buffers (`true`: read only).
            let place_layout =
                compute_layout(device, "hair followers", None, &[true, true, true, true, false, false, true, false]);
            let draw_layout = compute_layout(device, "hair followers", None, &[true, true, false]);
            let place = compute_pipeline(device, "place", FOLLOWERS_SHADER, "place", &place_layout);
            let draw = compute_pipeline(device, "draw", FOLLOWERS_SHADER, "draw", &draw_layout);
            let group = |layout: &wgpu::BindGroupLayout, buffers: &[&wgpu::Buffer]| {
                bind_whole_buffers(device, "hair followers", layout, buffers)
            };
            let place_group = group(
                &place_layout,
                &[
                    &params,
                    &nodes,
                    &guide_of_node,
                    &guide_data,
                    &colliders,
                    &placed[0],
                    &placed[1],
                    &guide_starts,
                    &guide_frames,
                ],
            );
            let draw_group = group(&draw_layout, &[&params, &placed[1], &placed[0], &drawn]);
            Self { target, guides_offset, place, draw, place_group, draw_group, drawn_nodes }
        }

        /// The followers' part of a step: gather, place, draw (as the renderer records them).
        fn record(&self, solver: &GpuStrandSolver, queue: &wgpu::Queue, encoder: &mut wgpu::CommandEncoder) {
            solver.record_gather(queue, encoder, &self.target, 0, self.guides_offset);
            let groups = self.drawn_nodes.div_ceil(64);
            let (x, y) = if groups > 65_535 { (65_535, groups.div_ceil(65_535)) } else { (groups, 1) };
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.place);
            pass.set_bind_group(0, &self.place_group, &[]);
            pass.dispatch_workgroups(x, y, 1);
            pass.set_pipeline(&self.draw);
            pass.set_bind_group(0, &self.draw_group, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
    }
}

/// The example's guides and followers per guide.
const EXAMPLE_GUIDES: usize = 2000;
const EXAMPLE_FOLLOWERS: usize = 10;

/// The guides the example's head is grown with in this run (`--guides N`; the example's 2 000 by
/// default), each with as many followers as keep its 22 000 hairs drawn.
static GUIDES: AtomicUsize = AtomicUsize::new(EXAMPLE_GUIDES);

/// The followers per guide of this run's groom: the example's 22 000 hairs over [`GUIDES`] guides.
fn followers_per_guide() -> usize {
    (EXAMPLE_GUIDES * (1 + EXAMPLE_FOLLOWERS)).div_ceil(GUIDES.load(Ordering::Relaxed)).max(1) - 1
}

/// The example's head (`examples/head.rs`) in `app`, with its groom of `style` (2 000 combed guides × 24
/// edges, 10 followers each, or [`GUIDES`] with [`followers_per_guide`]) and its colliders: skull and face
/// on the head; neck, shoulders and torso.
fn example_head(app: &mut bevy::prelude::App, style: HairStyle) -> bevy::prelude::Entity {
    use bevy::prelude::{ChildOf, Transform};
    let groom = HairGroom {
        scalp: example_scene::SCALP,
        strand_count: GUIDES.load(Ordering::Relaxed),
        segments: 24,
        style,
        seed: 1,
        followers_per_guide: followers_per_guide(),
        ..HairGroom::default()
    };
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, example_scene::NECK_HEIGHT, 0.0))).id();
    let on_head = [(example_scene::SCALP.centre, example_scene::SCALP.semi_axes), example_scene::FACE];
    for (centre, semi_axes) in on_head {
        let collider = HairCollider::ellipsoid(semi_axes);
        app.world_mut().spawn((collider, Transform::from_translation(centre), HairColliderOf(head), ChildOf(head)));
    }
    for part in example_scene::BODY {
        app.world_mut().spawn((part.collider(), part.transform(), HairColliderOf(head)));
    }
    head
}

/// An app with the example's head grown in `style` ([`example_head`]), the grid's velocity smoothing on
/// with a volume pressure of `pressure` Pa, the style held at `hold` 1/s, left still for `still_steps`
/// fixed steps.
fn example_app(
    threads: usize,
    style: HairStyle,
    (hold, pressure): (f32, f32),
    still_steps: usize,
) -> (bevy::prelude::App, bevy::prelude::Entity) {
    example_app_within(threads, style, (hold, pressure), still_steps, None)
}

/// [`example_app`] with a CPU budget of `budget` ms per update ([`HairCpuBudget`]), or none.
fn example_app_within(
    threads: usize,
    style: HairStyle,
    (hold, pressure): (f32, f32),
    still_steps: usize,
    budget: Option<f32>,
) -> (bevy::prelude::App, bevy::prelude::Entity) {
    let mut app = Scene::app(Some(threads));
    {
        let mut settings = app.world_mut().resource_mut::<HairSettings>();
        settings.volume = HairVolume { enabled: true, stiffness: pressure, ..HairVolume::default() };
        settings.style_hold = HairStyleHold { rate: hold, ..HairStyleHold::default() };
    }
    app.insert_resource(HairCpuBudget { milliseconds: budget, ..HairCpuBudget::default() });
    let head = example_head(&mut app, style);
    for _ in 0..still_steps {
        app.update();
    }
    (app, head)
}

/// How many steps old the hair's components are: 0 on the CPU, [`HairGpuStatus::read_back_age`] on the
/// GPU.
#[cfg(feature = "gpu")]
fn read_back_age(app: &bevy::prelude::App) -> usize {
    app.world().get_resource::<HairGpuStatus>().and_then(|status| status.read_back_age).unwrap_or(0) as usize
}

#[cfg(not(feature = "gpu"))]
fn read_back_age(_: &bevy::prelude::App) -> usize {
    0
}

/// [`example_app_within`] on the GPU, without a budget: a headless app with Bevy's renderer on whatever
/// adapter wgpu finds, the guides stepped on the GPU (the grid's there too) and read back after every step,
/// the followers placed on the CPU from them (so that the figures read the drawn hair from the
/// components), after a still second.
#[cfg(feature = "gpu")]
fn example_app_on_gpu(threads: usize, (hold, pressure): (f32, f32)) -> (bevy::prelude::App, bevy::prelude::Entity) {
    use bevy_hair_sim::followers::FollowerPlacement;
    let mut app = gpu::rendered_app(Some(threads));
    app.insert_resource(HairGpuSettings { read_back: GpuReadBackRate::EveryStep, ..Default::default() })
        .insert_resource(FollowerPlacement::Cpu);
    {
        let mut settings = app.world_mut().resource_mut::<HairSettings>();
        settings.volume = HairVolume { enabled: true, stiffness: pressure, ..HairVolume::default() };
        settings.style_hold = HairStyleHold { rate: hold, ..HairStyleHold::default() };
    }
    let head = example_head(&mut app, HairStyle::Straight);
    for _ in 0..60 {
        app.update();
    }
    let status = app.world().resource::<HairGpuStatus>();
    assert!(status.strands > 0, "the GPU steps the guides: {:?}", status.error);
    (app, head)
}

#[cfg(not(feature = "gpu"))]
fn example_app_on_gpu(_: usize, _: (f32, f32)) -> (bevy::prelude::App, bevy::prelude::Entity) {
    panic!("`coverage --gpu` needs the `gpu` feature");
}

/// The head shaken as the example shakes it, `t` s in: ±0.7 rad about the vertical at 1.8 Hz.
fn shaken(t: f32) -> bevy::prelude::Quat {
    bevy::prelude::Quat::from_rotation_y(0.7 * (std::f32::consts::TAU * 1.8 * t).sin())
}

/// Every hair of the head as drawn, world space: each guide's nodes and its followers'.
fn drawn_hairs<'w>(world: &'w bevy::prelude::World, strands: &[bevy::prelude::Entity]) -> Vec<&'w [Vec3]> {
    let mut hairs: Vec<&[Vec3]> = Vec::new();
    for &strand in strands {
        hairs.push(&world.get::<StrandNodes>(strand).expect("a strand").positions);
        if let Some(followers) = world.get::<FollowerNodes>(strand) {
            let per = followers.nodes_per_follower().max(1);
            hairs.extend(followers.positions.chunks_exact(per));
        }
    }
    hairs
}

/// The width the renderer draws the example's hairs, m: a fibre's diameter times the hairs each stands for.
fn drawn_width(world: &bevy::prelude::World, strand: bevy::prelude::Entity) -> f32 {
    let material = *world.get::<SimulatedStrand>(strand).expect("a strand").rod().material();
    let represented = world.get::<bevy_hair_sim::volume::RepresentedHairs>(strand).map_or(1, |hairs| hairs.0);
    2.0 * (material.semi_axis_1 * material.semi_axis_2).sqrt() as f32
        * (represented as f32 / (1 + followers_per_guide()) as f32).max(1.0)
}

/// Whether `point` (head-local, on the example's scalp) lies in the hairline's fade
/// ([`HairGroom::hairline_fade`]), where the example's groom draws its hair thinning out on purpose.
fn in_the_hairline_fade(point: Vec3) -> bool {
    example_scene::SCALP.depth_inside_hairline(point) < HairGroom::default().hairline_fade
}

/// The example's default scene (`examples/head.rs`: 2 000 combed straight guides × 24 edges with 10
/// followers each on its skull; skull, face, neck, shoulders and torso as colliders; the hair–hair grid's
/// velocity smoothing on), held still, shaken, turned and flicked as the example animates its head, for
/// `seconds` each from a fresh start after one still second: the scalp's exposure
/// ([`coverage::scalp_exposure`]: 2 000 points over the haired scalp, each hidden when the guides and
/// followers within 3 mm of it, drawn as wide as the renderer draws them, cover the 3 mm disc about it;
/// over the whole haired scalp, and over its points further inside the hairline than the groom's
/// [`HairGroom::hairline_fade`], where a bare point is a bald patch rather than the hairline's edge),
/// the scalp a camera behind the body and a little above sees through the hair ([`coverage::scalp_seen`]:
/// of the same points facing it, those the hair in front covers less than a 2 mm pixel of),
/// and the strays ([`coverage::StrayCheck`]: guides whose tip has moved more than 5 cm from where it was
/// after the still second relative to the mean tip of the 6 guides rooted nearest), the largest over the
/// run (every 0.1 s) and at its end; each motion with the style unheld and held near the roots
/// ([`HairStyleHold`] at 200/s).
fn coverage(
    threads: usize,
    seconds: f32,
    only: Option<&str>,
    air_damping: Option<f32>,
    budget: Option<f32>,
    on_gpu: bool,
) {
    use bevy::prelude::{Quat, Transform};
    use bevy_hair_sim::debug::coverage::{self, StrayCheck};
    let scalp = example_scene::SCALP;
    type Motion = fn(f32) -> Quat;
    let motions: [(&str, Motion); 4] = [
        ("rest", |_| Quat::IDENTITY),
        ("shake", shaken),
        ("turn", |t| Quat::from_rotation_y(1.2 * (std::f32::consts::TAU * 0.3 * t).sin())),
        ("flick", |t| {
            let s = ((t - 1.0) / 0.3).clamp(0.0, 1.0);
            Quat::from_rotation_y(0.8 * s * s * (3.0 - 2.0 * s))
        }),
    ];
    println!();
    // A camera behind the body and a little above it (the face looks along −Z).
    const BEHIND: Vec3 = Vec3::new(0.0, 0.3, 1.0);
    let air = air_damping.unwrap_or(HairSettings::default().air_damping);
    println!(
        "The example's scene moving, {seconds} s each, stepped on the {}, air drag {air}/s, {} after the still second: scalp seen from behind (2 mm pixels the hair in front covers less than), scalp exposure (hair within 3 mm hiding less than the 3 mm disc), over the whole haired scalp and past the hairline's fade ({} mm in, where the groom thins its hair on purpose), and strays (tips 5 cm off their 6 neighbours'):",
        if on_gpu { "GPU (read back every step; the followers placed on the CPU)" } else { "CPU" },
        budget_words(budget),
        1e3 * HairGroom::default().hairline_fade
    );
    println!(
        "| motion | style hold, 1/s | pressure, Pa | seen from behind, largest | at the end | exposure, largest | at the end | past the fade, largest | at the end | strays, largest | at the end |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    // Unheld; held at the example's 200/s (see `HairStyleHold`); held, with the grid's pressure against
    // the groom's packing.
    let settings = [(0.0, 0.0), (200.0, 0.0), (200.0, 50.0)];
    let motions = motions.into_iter().filter(|(name, _)| only.is_none_or(|only| only == *name));
    let runs = motions.flat_map(|motion| settings.iter().map(move |&setting| (motion, setting)));
    for ((name, rotation), (hold, pressure)) in runs {
        let (mut app, head) = if on_gpu {
            example_app_on_gpu(threads, (hold, pressure))
        } else {
            example_app_within(threads, HairStyle::Straight, (hold, pressure), 60, budget)
        };
        if let Some(air_damping) = air_damping {
            app.world_mut().resource_mut::<HairSettings>().air_damping = air_damping;
        }
        let head_pose = |app: &bevy::prelude::App| {
            let transform = app.world().get::<Transform>(head).expect("the head exists");
            bevy::math::Affine3A::from_rotation_translation(transform.rotation, transform.translation)
        };
        let strands: Vec<bevy::prelude::Entity> =
            app.world().get::<HeadStrands>(head).expect("the groom grew").strands().to_vec();
        let to_local = head_pose(&app).inverse();
        let roots: Vec<Vec3> = strands
            .iter()
            .map(|&strand| to_local.transform_point3(app.world().get::<StrandNodes>(strand).unwrap().positions[0]))
            .collect();
        let rest_tips: Vec<Vec3> = strands
            .iter()
            .map(|&strand| *app.world().get::<StrandNodes>(strand).unwrap().positions.last().expect("nodes"))
            .collect();
        let strays = StrayCheck::new(&roots, 6, &head_pose(&app), &rest_tips);
        let width = drawn_width(app.world(), strands[0]);
        // The hair as last read back from the GPU is that many steps old: measured against the head's pose
        // at that step (which the figures on the CPU's hair need not: it is current).
        let measure = |app: &bevy::prelude::App, step: usize| {
            let pose = |app: &bevy::prelude::App| {
                let current = head_pose(app);
                let then = step.saturating_sub(read_back_age(app)) as f32 / 60.0;
                bevy::math::Affine3A::from_rotation_translation(rotation(then), current.translation.into())
            };
            let world = app.world();
            let hairs = drawn_hairs(world, &strands);
            let tips: Vec<Vec3> = strands
                .iter()
                .map(|&strand| *world.get::<StrandNodes>(strand).expect("a strand").positions.last().expect("nodes"))
                .collect();
            let bare = coverage::bare_scalp(&scalp, &pose(app), hairs.iter().copied(), 2000, (0.003, width))
                .expect("the scalp");
            let past_the_fade = bare.points.iter().filter(|root| !in_the_hairline_fade(root.position)).count();
            let share = |count: usize| count as f32 / bare.judged as f32;
            let seen =
                coverage::scalp_seen(&scalp, &pose(app), hairs, 2000, BEHIND, (0.002, width)).expect("the scalp");
            let strays = strays.stray_fraction(&pose(app), &tips, 0.05);
            [seen, share(bare.points.len()), share(past_the_fade), strays]
        };
        let (mut largest, mut last) = ([0.0_f32; 4], [0.0_f32; 4]);
        let steps = (seconds * 60.0).round() as usize;
        for step in 1..=steps {
            app.world_mut().get_mut::<Transform>(head).expect("the head exists").rotation =
                rotation(step as f32 / 60.0);
            app.update();
            if step % 6 == 0 || step == steps {
                last = measure(&app, step);
                largest = std::array::from_fn(|figure| largest[figure].max(last[figure]));
            }
        }
        let [seen, exposure, past_the_fade, strays] =
            std::array::from_fn(|figure| (100.0 * largest[figure], 100.0 * last[figure]));
        println!(
            "| {name} | {hold} | {pressure} | {:.1} % | {:.1} % | {:.1} % | {:.1} % | {:.1} % | {:.1} % | {:.2} % | {:.2} % |",
            seen.0, seen.1, exposure.0, exposure.1, past_the_fade.0, past_the_fade.1, strays.0, strays.1
        );
    }
}

/// Where the example's scalp is bare ([`coverage::bare_scalp`], as `coverage` judges it) after
/// `seconds` still, held as the example holds it: of the scalp's 2 000 points in each part (by the
/// skull's normal's up component, its side, and within 1 cm of the parting), how many are bare, and how
/// many of those lie in the hairline's fade ([`HairGroom::hairline_fade`], 8 mm), where the hair is drawn
/// thinning out on purpose.
fn bare_regions(threads: usize, seconds: f32) {
    use bevy_hair_sim::debug::coverage;
    use bevy_hair_sim::groom::ScalpRoot;
    let scalp = example_scene::SCALP;
    let (mut app, head) = example_app(threads, HairStyle::Straight, (200.0, 50.0), 60);
    for _ in 0..(seconds * 60.0) as usize {
        app.update();
    }
    let strands: Vec<bevy::prelude::Entity> =
        app.world().get::<HeadStrands>(head).expect("the groom grew").strands().to_vec();
    let width = drawn_width(app.world(), strands[0]);
    let transform = app.world().get::<bevy::prelude::Transform>(head).expect("the head exists");
    let pose = bevy::math::Affine3A::from_rotation_translation(transform.rotation, transform.translation);
    let hairs = drawn_hairs(app.world(), &strands);
    let bare = coverage::bare_scalp(&scalp, &pose, hairs, 2000, (0.003, width)).expect("the scalp");
    let part = |&ScalpRoot { position, normal }: &ScalpRoot| {
        let height = match normal.y {
            y if y > 0.7 => "top",
            y if y > 0.3 => "upper",
            y if y > 0.0 => "above the widest",
            _ => "below the widest",
        };
        let side = if normal.z < -0.5 {
            "front"
        } else if normal.z > 0.5 {
            "back"
        } else {
            "sides"
        };
        let parting = (position.x - scalp.centre.x - 0.02).abs() < 0.01 && normal.y > 0.3;
        (height, side, parting)
    };
    let mut counts: std::collections::BTreeMap<(&str, &str, bool), [usize; 3]> = Default::default();
    for root in scalp.roots(2000).expect("the scalp") {
        counts.entry(part(&root)).or_default()[0] += 1;
    }
    for root in &bare.points {
        let count = counts.entry(part(root)).or_default();
        count[1] += 1;
        count[2] += usize::from(in_the_hairline_fade(root.position));
    }
    println!();
    println!("The example's scalp after {seconds} s still (held at 200/s, 50 Pa): where it is bare");
    println!(
        "| part | side | at the parting | points | bare | of them in the hairline's fade ({} mm) |",
        1e3 * HairGroom::default().hairline_fade
    );
    println!("|---|---|---|---:|---:|---:|");
    for ((height, side, parting), [all, bare, near]) in counts {
        println!("| {height} | {side} | {} | {all} | {bare} | {near} |", if parting { "yes" } else { "" });
    }
    println!("| all | | | {} | {} | |", bare.judged, bare.points.len());
}

/// What holding the style costs the example's scene ([`example_head`], the grid's smoothing on): the
/// straight groom shaken as `coverage` shakes it, unheld and held at 200/s, stepped in turn after a still
/// second (one interleaved run): median ms per update, and the Newton iterations per strand.
fn hold_cost(threads: usize, steps: usize) {
    use bevy::prelude::Transform;
    println!();
    println!("| the example's scene shaken | ms per update | Newton iterations per strand |");
    println!("|---|---:|---:|");
    let rows = [("unheld", 0.0), ("held at 200/s", 200.0)];
    let mut apps: Vec<(bevy::prelude::App, bevy::prelude::Entity)> =
        rows.iter().map(|&(_, hold)| example_app(threads, HairStyle::Straight, (hold, 0.0), 60)).collect();
    let mut times = vec![Vec::with_capacity(steps); rows.len()];
    let mut iterations = vec![0.0; rows.len()];
    for step in 1..=steps {
        let rotation = shaken(step as f32 / 60.0);
        for (index, (app, head)) in apps.iter_mut().enumerate() {
            app.world_mut().get_mut::<Transform>(*head).expect("the head exists").rotation = rotation;
            let started = Instant::now();
            app.update();
            times[index].push(started.elapsed().as_secs_f64());
            iterations[index] += app.world().resource::<HairStatistics>().mean_newton_iterations / steps as f64;
        }
    }
    for (((name, _), times), iterations) in rows.iter().zip(&mut times).zip(&iterations) {
        println!("| {name} | {:.2} | {iterations:.2} |", 1e3 * median(times));
    }
}

/// The example's default scene as the example runs it ([`example_head`]: 2 000 combed guides × 24 edges,
/// 10 followers each, its five colliders, the grid's velocity smoothing on, the style held at 200/s),
/// still and shaken as the example shakes it, each for `steps` updates after a still second: median ms
/// per whole update and, from [`HairStatistics`], the median of its parts: stepping the guides, placing
/// the followers and the hair–hair grid (the target is the whole in 10 ms). Twice: with the followers
/// placed on the CPU (a headless game's default) and on the GPU, as the example's renderer places them
/// ([`FollowerPlacement::Gpu`]; what the CPU still does for them, packing the guides' poses in the step
/// and their upload, is not in this headless app: `render` measures it).
fn example_scene_cost(threads: usize, steps: usize) {
    use bevy::prelude::Transform;
    use bevy_hair_sim::followers::FollowerPlacement;
    println!();
    println!("The example's default scene ({threads} threads), ms per update (medians; target for the whole: 10 ms):");
    println!(
        "| motion | followers placed | whole update | guides | followers | grid | the rest | Newton iterations per guide |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    type Motion = fn(f32) -> bevy::prelude::Quat;
    let motions: [(&str, Motion); 2] = [("still", |_| bevy::prelude::Quat::IDENTITY), ("shaken", shaken)];
    for (placement, placed) in [(FollowerPlacement::Cpu, "on the CPU"), (FollowerPlacement::Gpu, "on the GPU")] {
        for (name, rotation) in motions {
            let (mut app, head) = example_app(threads, HairStyle::Straight, (200.0, 0.0), 60);
            app.insert_resource(placement);
            let mut parts = [(); 5].map(|_| Vec::with_capacity(steps));
            let mut iterations = Vec::with_capacity(steps);
            for step in 1..=steps {
                app.world_mut().get_mut::<Transform>(head).expect("the head exists").rotation =
                    rotation(step as f32 / 60.0);
                let started = Instant::now();
                app.update();
                let whole = started.elapsed().as_secs_f64();
                let statistics = app.world().resource::<HairStatistics>();
                let (guides, followers, grid) =
                    (statistics.step_seconds, statistics.follower_seconds, statistics.volume_seconds);
                iterations.push(statistics.mean_newton_iterations);
                for (part, seconds) in
                    parts.iter_mut().zip([whole, guides, followers, grid, whole - guides - followers - grid])
                {
                    part.push(seconds);
                }
            }
            let [whole, guides, followers, grid, rest] = parts.each_mut().map(|times| 1e3 * median(times));
            let iterations = iterations.iter().sum::<f64>() / steps as f64;
            println!(
                "| {name} | {placed} | {whole:.1} | {guides:.1} | {followers:.1} | {grid:.1} | {rest:.1} | {iterations:.2} |"
            );
        }
    }
}

/// Every style of the example (`examples/head.rs`, as [`example_head`] grows it) left still for
/// `seconds` on the head after its groom grew: how far the guides stand from their groomed shape (RMS and
/// largest over their nodes), the strays against the groomed shape ([`coverage::StrayCheck`]: tips 3 cm
/// off their 6 neighbours'), and the share of the face below the hairline and of the eyes a camera in
/// front sees hidden by hair ([`coverage::share_seen`], 1 mm pixels); unheld, held as the example holds
/// it, and held with the grid's pressure (50 Pa). With a `budget` (ms, [`HairCpuBudget`]) the hair runs
/// within it, and a last column says how far its guides are drawn from where the same run without the
/// budget draws them (RMS over their nodes).
fn styles_at_rest(threads: usize, seconds: f32, styles: &[HairStyle], budget: Option<f32>) {
    use bevy::prelude::Transform;
    use bevy_hair_sim::debug::coverage::{self, StrayCheck};
    println!();
    println!(
        "Every style at rest after {seconds} s (the example's head and colliders, grid on), {}: distance of the guides' nodes from the groomed shape, strays against it (tips 3 cm off their 6 neighbours'), face below the hairline and eyes hidden by hair seen from the front (1 mm pixels){}:",
        budget_words(budget),
        if budget.is_some() { ", and the drawn guides' distance from the run without a budget" } else { "" }
    );
    println!(
        "| style | style hold, 1/s | pressure, Pa | from groomed, RMS mm | largest, mm | strays | face hidden | eyes hidden |{}",
        if budget.is_some() { " from the unbudgeted, RMS mm |" } else { "" }
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|{}", if budget.is_some() { "---:|" } else { "" });
    let (face, eyes) = example_face_points();
    let still_steps = (seconds * 60.0).round() as usize;
    for &style in styles {
        for (hold, pressure) in [(0.0, 0.0), (0.0, 50.0), (200.0, 0.0), (200.0, 50.0)] {
            let (app, head) = example_app_within(threads, style, (hold, pressure), still_steps, budget);
            let world = app.world();
            let transform = world.get::<Transform>(head).expect("the head exists");
            let pose = bevy::math::Affine3A::from_rotation_translation(transform.rotation, transform.translation);
            let strands = world.get::<HeadStrands>(head).expect("the groom grew").strands().to_vec();
            // The head has not moved: the groomed shape is where each strand was spawned.
            let (mut squared, mut count, mut largest) = (0.0_f64, 0_usize, 0.0_f64);
            let (mut roots, mut groomed_tips, mut tips) = (Vec::new(), Vec::new(), Vec::new());
            for &strand in &strands {
                let rod = world.get::<SimulatedStrand>(strand).expect("every strand built").rod();
                for (now, groomed) in rod.positions().iter().zip(rod.initial_positions()) {
                    let distance = now.distance(*groomed);
                    (squared, count, largest) = (squared + distance * distance, count + 1, largest.max(distance));
                }
                let (first, last) = (rod.initial_positions()[0], rod.initial_positions()[rod.node_count() - 1]);
                roots.push(pose.inverse().transform_point3(first.as_vec3()));
                groomed_tips.push(last.as_vec3());
                tips.push(rod.positions()[rod.node_count() - 1].as_vec3());
            }
            let strays = StrayCheck::new(&roots, 6, &pose, &groomed_tips).stray_fraction(&pose, &tips, 0.03);
            let hairs = drawn_hairs(world, &strands);
            let width = drawn_width(world, strands[0]);
            let in_front = pose.transform_vector3(Vec3::NEG_Z);
            let hidden = |points: &[Vec3]| {
                let points: Vec<Vec3> = points.iter().map(|&point| pose.transform_point3(point)).collect();
                1.0 - coverage::share_seen(&points, hairs.iter().copied(), in_front, (0.001, width))
            };
            let from_unbudgeted = match budget {
                None => String::new(),
                Some(_) => {
                    let (reference, reference_head) = example_app(threads, style, (hold, pressure), still_steps);
                    let reference_strands =
                        reference.world().get::<HeadStrands>(reference_head).expect("the groom grew").strands();
                    let (mut squared, mut count) = (0.0_f64, 0_usize);
                    for (&strand, &reference_strand) in strands.iter().zip(reference_strands) {
                        let drawn = &world.get::<StrandNodes>(strand).expect("a strand").positions;
                        let unbudgeted =
                            &reference.world().get::<StrandNodes>(reference_strand).expect("a strand").positions;
                        for (node, reference_node) in drawn.iter().zip(unbudgeted) {
                            squared += f64::from(node.distance_squared(*reference_node));
                            count += 1;
                        }
                    }
                    format!(" {:.2} |", 1e3 * (squared / count.max(1) as f64).sqrt())
                }
            };
            println!(
                "| {} | {hold} | {pressure} | {:.2} | {:.1} | {:.2} % | {:.1} % | {:.1} % |{from_unbudgeted}",
                style.name(),
                1e3 * (squared / count as f64).sqrt(),
                1e3 * largest,
                100.0 * strays,
                100.0 * hidden(&face),
                100.0 * hidden(&eyes)
            );
        }
    }
}

/// "no CPU budget", or "within a CPU budget of `budget` ms per update".
fn budget_words(budget: Option<f32>) -> String {
    budget.map_or_else(|| "no CPU budget".to_owned(), |budget| format!("within a CPU budget of {budget} ms per update"))
}

/// The example's default scene (as [`example_scene_cost`] runs it, the followers placed on the GPU as the
/// example places them) with no CPU budget, within 4 ms and within 2 ms per update ([`HairCpuBudget`]), and
/// held at step intervals of 2, 4, 8 and 16 fixed steps and carried ([`HairDetail::fixed`], what each of the
/// budget's intervals costs, and its floor), still and shaken: the apps stepped in turn for `steps` updates
/// after two still seconds (the budget's choice settles in them), so that the machine's drifts fall on all
/// alike. Per update, ms: the mean, the 95th percentile and the largest of the whole `app.update()`, the
/// updates over the budget, the hair's own clock ([`HairStatistics::update_seconds`], mean) and its parts,
/// and the step intervals the budget used.
fn budgeted_scene_cost(threads: usize, steps: usize, only_setting: Option<&str>, only_motion: Option<&str>) {
    use bevy::prelude::Transform;
    use bevy_hair_sim::followers::FollowerPlacement;
    println!();
    println!(
        "The example's default scene within a CPU budget ({threads} threads, followers placed on the GPU as the example places them), ms per update over {steps} updates:"
    );
    println!(
        "| motion | budget, ms, or level held | mean | 95th percentile | largest | updates over the budget | hair's own clock, mean | of it: guides, grid | step intervals used | Newton iterations per stepped guide |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---|---|---:|");
    type Motion = fn(f32) -> bevy::prelude::Quat;
    let motions: [(&str, Motion); 2] = [("still", |_| bevy::prelude::Quat::IDENTITY), ("shaken", shaken)];
    #[derive(Clone, Copy)]
    enum Setting {
        Budget(Option<f32>),
        Held(HairDetailLevel),
    }
    let settings = [
        Setting::Budget(None),
        Setting::Budget(Some(4.0)),
        Setting::Budget(Some(2.0)),
        Setting::Held(HairDetailLevel::Stepped(2)),
        Setting::Held(HairDetailLevel::Stepped(4)),
        Setting::Held(HairDetailLevel::Stepped(8)),
        Setting::Held(HairDetailLevel::Stepped(16)),
        Setting::Held(HairDetailLevel::Carried),
    ];
    struct Run {
        motion: (&'static str, Motion),
        setting: Setting,
        app: bevy::prelude::App,
        head: bevy::prelude::Entity,
        times: Vec<f64>,
        own: Vec<f64>,
        parts: [f64; 2],
        intervals: std::collections::BTreeSet<u32>,
        iterations: f64,
    }
    let setting_name = |setting: Setting| match setting {
        Setting::Budget(None) => "none".to_owned(),
        Setting::Budget(Some(budget)) => budget.to_string(),
        Setting::Held(HairDetailLevel::Stepped(interval)) => format!("every-{interval}"),
        Setting::Held(HairDetailLevel::Carried) => "carried".to_owned(),
    };
    let mut runs: Vec<Run> = motions
        .into_iter()
        .filter(|motion| only_motion.is_none_or(|name| name == motion.0))
        .flat_map(|motion| settings.map(|setting| (motion, setting)))
        .filter(|&(_, setting)| only_setting.is_none_or(|name| name == setting_name(setting)))
        .map(|(motion, setting)| {
            let budget = match setting {
                Setting::Budget(budget) => budget,
                Setting::Held(_) => None,
            };
            let (mut app, head) = example_app_within(threads, HairStyle::Straight, (200.0, 0.0), 0, budget);
            app.insert_resource(FollowerPlacement::Gpu);
            if let Setting::Held(level) = setting {
                app.world_mut().entity_mut(head).insert(HairDetail::fixed(level));
            }
            for _ in 0..120 {
                app.update();
            }
            let intervals = std::collections::BTreeSet::new();
            Run { motion, setting, app, head, times: vec![], own: vec![], parts: [0.0; 2], intervals, iterations: 0.0 }
        })
        .collect();
    for step in 1..=steps {
        for run in &mut runs {
            run.app.world_mut().get_mut::<Transform>(run.head).expect("the head exists").rotation =
                (run.motion.1)(step as f32 / 60.0);
            let started = Instant::now();
            run.app.update();
            run.times.push(started.elapsed().as_secs_f64());
            let statistics = run.app.world().resource::<HairStatistics>();
            run.own.push(statistics.update_seconds);
            for (sum, part) in run.parts.iter_mut().zip([statistics.step_seconds, statistics.volume_seconds]) {
                *sum += 1e3 * part / steps as f64;
            }
            run.intervals.insert(statistics.budget_step_interval);
            run.iterations += statistics.mean_newton_iterations / steps as f64;
        }
    }
    for run in &mut runs {
        let mean = 1e3 * run.times.iter().sum::<f64>() / run.times.len() as f64;
        let own = 1e3 * run.own.iter().sum::<f64>() / run.own.len() as f64;
        let (setting, over) = match run.setting {
            Setting::Budget(None) => ("none".to_owned(), "".to_owned()),
            Setting::Budget(Some(budget)) => {
                let over = run.times.iter().filter(|&&time| 1e3 * time > f64::from(budget)).count();
                (budget.to_string(), over.to_string())
            }
            Setting::Held(HairDetailLevel::Stepped(interval)) => {
                (format!("held: every {interval} fixed steps"), String::new())
            }
            Setting::Held(HairDetailLevel::Carried) => ("held carried".to_owned(), String::new()),
        };
        run.times.sort_by(f64::total_cmp);
        let percentile = 1e3 * run.times[(run.times.len() * 95).div_ceil(100) - 1];
        let largest = 1e3 * run.times[run.times.len() - 1];
        let intervals: Vec<String> = run.intervals.iter().map(u32::to_string).collect();
        println!(
            "| {} | {setting} | {mean:.2} | {percentile:.2} | {largest:.2} | {over} | {own:.2} | {:.2}, {:.2} | {} | {:.2} |",
            run.motion.0,
            run.parts[0],
            run.parts[1],
            intervals.join(", "),
            run.iterations
        );
    }
}

/// The example's face below the hairline as seen from in front, head-local: points 2 mm apart from the
/// chin to 1 cm under the hairline and between the outer corners of the eyes, each on the frontmost of the
/// skull, the face and the eyes; and those of them on the eyes.
fn example_face_points() -> (Vec<Vec3>, Vec<Vec3>) {
    use example_scene::{EYE_RADIUS, EYES};
    // The front of an ellipsoid seen along +Z at (x, y), if it is there.
    let front = |centre: Vec3, semi_axes: Vec3, x: f32, y: f32| {
        let (u, v) = ((x - centre.x) / semi_axes.x, (y - centre.y) / semi_axes.y);
        (u * u + v * v < 1.0).then(|| centre.z - semi_axes.z * (1.0 - u * u - v * v).sqrt())
    };
    let (mut face, mut eyes) = (Vec::new(), Vec::new());
    for row in 0..=65 {
        for column in 0..=40 {
            let (x, y) = (-0.04 + 0.002 * column as f32, 0.02 + 0.002 * row as f32);
            let shapes = [(example_scene::SCALP.centre, example_scene::SCALP.semi_axes), example_scene::FACE]
                .into_iter()
                .chain(EYES.map(|eye| (eye, Vec3::splat(EYE_RADIUS))));
            let Some(z) = shapes.filter_map(|(centre, semi_axes)| front(centre, semi_axes, x, y)).reduce(f32::min)
            else {
                continue;
            };
            let point = Vec3::new(x, y, z);
            face.push(point);
            if EYES.iter().any(|eye| Vec2::new(x - eye.x, y - eye.y).length() < EYE_RADIUS) {
                eyes.push(point);
            }
        }
    }
    (face, eyes)
}

/// A crowd of 10 heads × 200 strands × 32 edges around one camera that sees two of them up close (see
/// `support/src/bench_scene.rs`), stepped in turn: every head at full detail; levels of detail chosen from
/// the camera with the eight others out of its view; and with four of them in view 4 to 7 m away. Median
/// ms per step, strands stepped per step, Newton iterations, the heads at each level.
fn crowd(threads: usize, steps: usize) {
    println!();
    println!("Crowd, 10 heads × 200 strands × 32 edges, the camera 1.2 m from two of them:");
    println!(
        "| levels of detail | other heads in view | ms / step | strands stepped per step | Newton iterations per strand | heads full / ½ / ¼ / carried |"
    );
    println!("|---|---:|---:|---:|---:|---|");
    let rows = [("off (all at full detail)", 0, false), ("on", 0, true), ("on", 4, true)];
    let mut crowds = rows.map(|(_, in_view, detail)| Crowd::new(10, in_view, 200, 32, Some(threads), detail));
    for crowd in &mut crowds {
        for _ in 0..WARM_UP_STEPS {
            crowd.step();
        }
    }
    let mut times = rows.map(|_| Vec::with_capacity(steps));
    let (mut stepped, mut iterations) = ([0; 3], [0.0; 3]);
    for _ in 0..steps {
        for (index, crowd) in crowds.iter_mut().enumerate() {
            let started = Instant::now();
            crowd.step();
            times[index].push(started.elapsed().as_secs_f64());
            let statistics = crowd.app.world().resource::<HairStatistics>();
            stepped[index] += statistics.strands;
            iterations[index] += statistics.mean_newton_iterations * statistics.strands as f64;
        }
    }
    for (index, (name, in_view, _)) in rows.into_iter().enumerate() {
        let step = median(&mut times[index]);
        let HeadsByDetail { full, every_second_step: half, rarer: quarter, carried } = crowds[index].levels();
        println!(
            "| {name} | {in_view} | {:.2} | {:.0} | {:.2} | {full} / {half} / {quarter} / {carried} |",
            1e3 * step,
            stepped[index] as f64 / steps as f64,
            iterations[index] / stepped[index] as f64
        );
    }
}

/// The plugin's app on `threads` threads with one head of `guides` combed guides × `edges` edges, each with
/// `followers` followers, at the benchmark's first pose.
fn groomed_head(
    threads: usize,
    guides: usize,
    followers: usize,
    edges: usize,
) -> (bevy::prelude::App, bevy::prelude::Entity) {
    let mut app = Scene::app(Some(threads));
    let groom =
        HairGroom { strand_count: guides, followers_per_guide: followers, segments: edges, ..HairGroom::default() };
    let head = app.world_mut().spawn((HairHead, groom, bevy::prelude::Transform::from_xyz(0.0, 1.6, 0.0))).id();
    (app, head)
}

/// Moves `head` to the benchmark's pose at `step` and updates the app (one fixed step).
fn move_head(app: &mut bevy::prelude::App, head: bevy::prelude::Entity, step: usize) {
    let (translation, rotation) = Scene::head_pose(step);
    let mut transform = app.world_mut().get_mut::<bevy::prelude::Transform>(head).expect("the head exists");
    (transform.translation, transform.rotation) = (translation, rotation);
    app.update();
}

/// What the hair renderer does on the CPU each frame ([`bevy_hair_sim::render`]) for 20 000 drawn strands
/// × 24 edges (2 000 guides with 9 followers each, moving): checking the layout, writing the node positions
/// interpolated between steps (with their bounds), and the copy `write_buffer` makes into the GPU's staging
/// memory (timed here as a copy of the same bytes into a buffer of that size). Median of `frames` frames, on
/// `threads` threads and on one.
fn render_preparation(threads: usize, frames: usize) {
    use bevy::prelude::Entity;
    use bevy_hair_sim::render::{GuideLayout, HairStrips};
    let edges = 24;
    let (mut app, head) = groomed_head(threads, 2000, 9, edges);
    for step in 0..WARM_UP_STEPS {
        move_head(&mut app, head, step);
    }
    let world = app.world();
    let strands: Vec<Entity> = world.get::<HeadStrands>(head).expect("the head has strands").strands().to_vec();
    let layout = || {
        strands.iter().filter_map(|&entity| {
            let nodes = world.get::<StrandNodes>(entity)?;
            Some(GuideLayout::new(entity, nodes, world.get::<FollowerNodes>(entity), 4e-5))
        })
    };
    let lookup = |entity| Some((world.get::<StrandNodes>(entity)?, world.get::<FollowerNodes>(entity)));
    let mut strips = HairStrips::default();
    strips.set_layout(layout());
    let drawn = strips.hairs().len();
    let mut staging = vec![0.0_f32; strips.positions().len()];
    println!();
    println!(
        "| {drawn} drawn strands × {edges} edges, {} nodes ({:.1} MB) | threads | layout check, ms | positions, ms | staging copy, ms | total, ms |",
        strips.node_count(),
        4.0 * staging.len() as f64 / 1e6
    );
    println!("|---|---:|---:|---:|---:|---:|");
    let median_ms = |values: &mut Vec<f64>| 1e3 * median(values);
    for threads in [threads, 1] {
        let mut samples = [Vec::new(), Vec::new(), Vec::new(), Vec::new()];
        for frame in 0..frames {
            let alpha = (frame % 7) as f32 / 7.0;
            let started = Instant::now();
            assert!(!strips.set_layout(layout()), "the layout holds");
            let checked = started.elapsed().as_secs_f64();
            let bounds = strips.fill(alpha, threads, lookup);
            assert!(bounds.is_some());
            let filled = started.elapsed().as_secs_f64();
            staging.copy_from_slice(strips.positions());
            std::hint::black_box(&staging);
            let copied = started.elapsed().as_secs_f64();
            for (sample, value) in samples.iter_mut().zip([checked, filled - checked, copied - filled, copied]) {
                sample.push(value);
            }
        }
        let [check, fill, copy, total] = &mut samples;
        println!(
            "| | {threads} | {:.2} | {:.2} | {:.2} | {:.2} |",
            median_ms(check),
            median_ms(fill),
            median_ms(copy),
            median_ms(total)
        );
    }
}

/// The example's scene (2 000 guides × 24 edges, 10 followers each, moving), one frame per step: the CPU's
/// work per frame for followers and drawing when the CPU places the followers and writes every drawn node
/// ([`FollowerPlacement::Cpu`]: the placement in the step, the layout check and `HairStrips::fill`),
/// against what it does when the GPU places and interpolates them ([`FollowerPlacement::Gpu`]: the step's
/// follower loop, which skips them, the step's packing of each guide's pose, and `GuideUpload::pack`,
/// which checks each guide against the layout as it copies its pose), alternating step by step in one
/// run; and the bytes each uploads per step. Median ms of `steps` steps each; in brackets, the part of
/// the draw preparation spent looking the layout over.
/// The step's packing is [`HairStatistics::pose_seconds`] (timed strand by strand, the clock's own cost
/// included) divided by the threads.
fn followers_on_the_gpu(threads: usize, steps: usize) {
    use bevy::prelude::Entity;
    use bevy_hair_sim::followers::FollowerPlacement;
    use bevy_hair_sim::render::feed::GuideUpload;
    use bevy_hair_sim::render::{DrawnStrand, GuideLayout, HairStrips};
    use bevy_hair_sim::simulation::PackedStrandPose;
    let (guides, followers, edges) = (2000, 10, 24);
    let (mut app, head) = groomed_head(threads, guides, followers, edges);
    let mut step = 0;
    let mut advance = |app: &mut bevy::prelude::App, placement: FollowerPlacement| {
        step += 1;
        app.insert_resource(placement);
        move_head(app, head, step);
        let statistics = app.world().resource::<HairStatistics>();
        (statistics.follower_seconds, statistics.pose_seconds / threads as f64)
    };
    for _ in 0..WARM_UP_STEPS {
        advance(&mut app, FollowerPlacement::Cpu);
    }
    let strands: Vec<Entity> = app.world().get::<HeadStrands>(head).expect("the head has strands").strands().to_vec();
    // As the renderer does when it lays the guides out for the GPU: the step packs their poses from now on.
    for &strand in &strands {
        let nodes = app.world().get::<StrandNodes>(strand).map_or(0, |nodes| nodes.positions.len());
        app.world_mut().entity_mut(strand).insert(PackedStrandPose::with_capacity(nodes));
    }
    // What the renderer reads of each strand, looked up as it does (`render::draw::prepare_hair_meshes`).
    let mut drawn = app.world_mut().query::<DrawnStrand>();
    let margin = HairSettings::default().collision_margin;
    let (mut strips, mut upload) = (HairStrips::default(), GuideUpload::default());
    let mut samples: [Vec<f64>; 7] = Default::default();
    let (mut cpu_bytes, mut gpu_bytes) = (0, 0);
    for frame in 0..2 * steps {
        let on_gpu = frame % 2 == 1;
        let placement = if on_gpu { FollowerPlacement::Gpu } else { FollowerPlacement::Cpu };
        let (placed, packed) = advance(&mut app, placement);
        let strand_query = drawn.query(app.world());
        let guide_now = |entity| {
            let (strand, nodes, followers, represented, _, pose) = strand_query.get(entity).ok()?;
            Some((GuideLayout::drawn(entity, strand, nodes, followers, represented), pose))
        };
        let layout = || strands.iter().filter_map(|&entity| Some(guide_now(entity)?.0));
        let followers_of = |guide: &GuideLayout| strand_query.get(guide.entity).ok().and_then(|strand| strand.2);
        let alpha = (frame % 7) as f32 / 7.0;
        // As the renderer does each frame: with the CPU's placement, the layout checked and every drawn node
        // written; with the GPU's, the head looked over only when it has no layout yet (or its strands
        // changed), and the guides packed, each checked against the layout on the way.
        let started = Instant::now();
        let checked;
        if on_gpu {
            if upload.guide_node_count() == 0 {
                strips.set_layout(layout());
                upload.set_layout(strips.guides().iter().map(|guide| (*guide, followers_of(guide))));
            }
            checked = started.elapsed().as_secs_f64();
            let unpacked = |entity, pose: &mut PackedStrandPose| {
                let Ok((strand, nodes, _, _, frames, _)) = strand_query.get(entity) else { return false };
                pose.write_from_components(nodes, frames, strand.collision_thickness(margin));
                true
            };
            let bounds = upload.pack(threads, &[], false, guide_now, unpacked).expect("the layout holds");
            assert!(bounds.is_some());
            gpu_bytes = upload.step_bytes();
        } else {
            assert!(!strips.set_layout(layout()) || frame == 0, "the layout holds");
            checked = started.elapsed().as_secs_f64();
            let lookup = |entity| strand_query.get(entity).ok().map(|(_, nodes, followers, ..)| (nodes, followers));
            assert!(strips.fill(alpha, threads, lookup).is_some());
            cpu_bytes = 4 * strips.positions().len();
        }
        let drawing = started.elapsed().as_secs_f64();
        let row = 3 * usize::from(on_gpu);
        samples[row].push(placed);
        samples[row + 1].push(checked);
        samples[row + 2].push(drawing);
        if on_gpu {
            samples[6].push(packed);
        }
    }
    let median_ms = |values: &mut Vec<f64>| 1e3 * median(values);
    let [cpu_placed, cpu_checked, cpu_drawn, gpu_placed, gpu_checked, gpu_drawn, gpu_packed] =
        samples.map(|mut values| median_ms(&mut values));
    println!();
    println!(
        "The example's scene, {guides} guides × {edges} edges with {followers} followers each, {threads} threads, one frame per step (interleaved):"
    );
    println!(
        "| followers placed | followers on the CPU, ms | poses packed in the step, ms | draw preparation (of it the layout check), ms | CPU total, ms | bytes uploaded per step |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    println!(
        "| on the CPU (`FollowerPlacement::Cpu`) | {cpu_placed:.2} | – | {cpu_drawn:.2} ({cpu_checked:.2}) | {:.2} | {cpu_bytes} |",
        cpu_placed + cpu_drawn
    );
    let gpu_total = gpu_placed + gpu_packed + gpu_drawn;
    println!(
        "| on the GPU (`FollowerPlacement::Gpu`) | {gpu_placed:.3} | {gpu_packed:.3} | {gpu_drawn:.2} ({gpu_checked:.3}) | {gpu_total:.2} | {gpu_bytes} |"
    );
    println!(
        "| ratio, CPU / GPU | | | | {:.1} | {:.1} |",
        (cpu_placed + cpu_drawn) / gpu_total,
        cpu_bytes as f64 / gpu_bytes as f64
    );
}

/// Hair–hair interaction ([`HairVolume`]) on the scene's 2 000 × 32 strands standing for 100 000 hairs
/// (50 each), on all five colliders: the grid off, on with its velocity smoothing (1 cm and 5 mm cells),
/// and with the volume pressure too (50 Pa, 5 mm), in turn (one interleaved run): median ms per update,
/// of the grid alone, and its share of the update.
fn volume_cost(threads: usize, steps: usize) {
    println!();
    println!("| 2 000 × 32, 5 colliders, 100 000 hairs | ms per update | grid, ms | grid share |");
    println!("|---|---:|---:|---:|");
    let on = HairVolume { enabled: true, ..HairVolume::default() };
    let rows = [
        ("grid off", HairVolume::default()),
        ("smoothing, 1 cm cells", HairVolume { cell_size: 0.01, ..on }),
        ("smoothing, 5 mm cells", on),
        ("smoothing and pressure (50 Pa), 5 mm", HairVolume { stiffness: 50.0, ..on }),
        (
            "the same, pressure against the target alone",
            HairVolume { stiffness: 50.0, keep_groomed_volume: false, ..on },
        ),
    ];
    let mut scenes: Vec<Scene> = rows
        .iter()
        .map(|(_, volume)| {
            let mut scene = Scene::new(2000, 32, Some(threads)).with_colliders(5);
            scene.app.world_mut().resource_mut::<HairSettings>().volume = *volume;
            let strands: Vec<_> = scene.app.world().get::<HeadStrands>(scene.head).expect("hair").strands().to_vec();
            for strand in strands {
                scene.app.world_mut().entity_mut(strand).insert(RepresentedHairs(50));
            }
            scene
        })
        .collect();
    scenes.iter_mut().for_each(Scene::warm_up);
    let mut times = vec![Vec::with_capacity(steps); rows.len()];
    let mut grid = vec![Vec::with_capacity(steps); rows.len()];
    for _ in 0..steps {
        for (index, scene) in scenes.iter_mut().enumerate() {
            let started = Instant::now();
            scene.step();
            times[index].push(started.elapsed().as_secs_f64());
            grid[index].push(scene.app.world().resource::<HairStatistics>().volume_seconds);
        }
    }
    for ((name, _), (times, grid)) in rows.iter().zip(times.iter_mut().zip(&mut grid)) {
        let (update, grid) = (median(times), median(grid));
        println!("| {name} | {:.2} | {:.2} | {:.1} % |", 1e3 * update, 1e3 * grid, 100.0 * grid / update);
    }
}

/// The time integrators and the wind on the scene's 2 000 × 32 strands, stepped in turn (one interleaved
/// run): median ms per step and mean Newton iterations per strand, without colliders and on all five.
fn integrators(threads: usize, steps: usize) {
    println!();
    println!("| 2 000 × 32, colliders | integrator, air | ms per step | Newton iterations per strand |");
    println!("|---|---|---:|---:|");
    let rows = [
        ("backward Euler, still", Integrator::BackwardEuler, HairWind::default()),
        ("BDF2, still", Integrator::Bdf2, HairWind::default()),
        (
            "BDF2, 3 m/s wind with gusts",
            Integrator::Bdf2,
            HairWind { velocity: Vec3::new(3.0, 0.0, 0.0), gusts: 1.0, ..HairWind::default() },
        ),
        (
            "BDF2, 3 m/s wind with gusts and turbulence",
            Integrator::Bdf2,
            HairWind { velocity: Vec3::new(3.0, 0.0, 0.0), gusts: 1.0, turbulence: 0.5, ..HairWind::default() },
        ),
    ];
    for colliders in [0, 5] {
        let mut scenes: Vec<Scene> = rows
            .iter()
            .map(|(_, integrator, wind)| {
                let mut scene = Scene::new(2000, 32, Some(threads)).with_colliders(colliders);
                scene.app.world_mut().resource_mut::<HairSettings>().integrator = *integrator;
                scene.app.insert_resource(wind.clone());
                scene
            })
            .collect();
        scenes.iter_mut().for_each(Scene::warm_up);
        let mut times = vec![Vec::with_capacity(steps); scenes.len()];
        let mut iterations = vec![0.0; scenes.len()];
        for _ in 0..steps {
            for (index, scene) in scenes.iter_mut().enumerate() {
                let started = Instant::now();
                scene.step();
                times[index].push(started.elapsed().as_secs_f64());
                iterations[index] += scene.app.world().resource::<HairStatistics>().mean_newton_iterations;
            }
        }
        for (index, (name, ..)) in rows.iter().enumerate() {
            let step = median(&mut times[index]);
            println!("| {colliders} | {name} | {:.2} | {:.2} |", 1e3 * step, iterations[index] / steps as f64);
        }
    }
}

/// Colliders baked from meshes: the baking time of icospheres of 2 000 to 40 500 triangles at 64 and
/// 128 cells along their side (fastest of three), then what a baked 10 cm ball costs a step against the
/// analytic sphere it stands for (1 000 strands × 32 edges on the moving head, scenes stepped in turn).
fn mesh_collider_cost(threads: usize, steps: usize) {
    use bevy::prelude::{Meshable, Sphere, Transform};
    println!();
    println!("Colliders baked from meshes (icospheres, r = 10 cm):");
    println!("| triangles | cells along a side | samples | ms per bake |");
    println!("|---:|---:|---:|---:|");
    for subdivisions in [9, 21, 44] {
        let mesh = Sphere::new(0.1).mesh().ico(subdivisions).expect("a few subdivisions");
        let triangles = mesh.indices().map_or(0, |indices| indices.len() / 3);
        for resolution in [64, 128] {
            let settings = MeshColliderSettings { resolution, ..MeshColliderSettings::default() };
            let mut samples = 0;
            let fastest = (0..3)
                .map(|_| {
                    let started = Instant::now();
                    let collider = HairCollider::from_mesh(&mesh, settings).expect("an icosphere bakes");
                    let seconds = started.elapsed().as_secs_f64();
                    if let ColliderShape::Mesh { field, .. } = &collider.shape {
                        samples = field.sample_counts().iter().product::<usize>();
                    }
                    seconds
                })
                .fold(f64::INFINITY, f64::min);
            println!("| {triangles} | {resolution} | {samples} | {:.0} |", 1e3 * fastest);
        }
    }
    let ball = Sphere::new(0.1).mesh().ico(21).expect("21 subdivisions");
    let baked = HairCollider::from_mesh(&ball, MeshColliderSettings::default()).expect("an icosphere bakes");
    let mut scenes = [
        Scene::new(1000, 32, Some(threads)),
        Scene::new(1000, 32, Some(threads)).with_collider(HairCollider::sphere(0.1), Transform::default()),
        Scene::new(1000, 32, Some(threads)).with_collider(baked, Transform::default()),
    ];
    let seconds = interleaved_median_step_seconds(&mut scenes, steps);
    println!();
    println!("| 1 000 strands × 32 edges, collider | ms / step | the collider's share, ms |");
    println!("|---|---:|---:|");
    let without = seconds[0];
    for (name, seconds) in
        ["none", "sphere, r = 10 cm", "baked icosphere, 9 680 triangles, 64 cells"].iter().zip(seconds)
    {
        println!("| {name} | {:.2} | {:.2} |", 1e3 * seconds, 1e3 * (seconds - without));
    }
}

/// Guides with followers: a combed groom of `guides` × 24 edges with `followers` each on a skull collider,
/// the head swaying and turning as in the other tables; median per step of the simulation (the guides'
/// step), the followers' placement and the whole update.
fn followers_cost(threads: usize, steps: usize) {
    use bevy::prelude::{ChildOf, Transform};
    println!();
    println!("| guides × followers × edges | drawn strands | simulation, ms | followers, ms | whole update, ms |");
    println!("|---|---:|---:|---:|---:|");
    for (guides, followers) in [(1000, 0), (1000, 10), (1000, 20), (2000, 10)] {
        let mut app = Scene::app(Some(threads));
        let groom =
            HairGroom { strand_count: guides, followers_per_guide: followers, segments: 24, ..HairGroom::default() };
        let skull = groom.scalp.semi_axes;
        let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
        app.world_mut().spawn((HairCollider::ellipsoid(skull), HairColliderOf(head), ChildOf(head)));
        let mut samples = [Vec::new(), Vec::new(), Vec::new()];
        for step in 0..WARM_UP_STEPS + steps {
            let (translation, rotation) = Scene::head_pose(step);
            let mut transform = app.world_mut().get_mut::<Transform>(head).expect("the head exists");
            (transform.translation, transform.rotation) = (translation, rotation);
            let started = Instant::now();
            app.update();
            let whole = started.elapsed().as_secs_f64();
            if step >= WARM_UP_STEPS {
                let statistics = app.world().resource::<HairStatistics>();
                for (sample, value) in
                    samples.iter_mut().zip([statistics.step_seconds, statistics.follower_seconds, whole])
                {
                    sample.push(value);
                }
            }
        }
        let median_ms = |values: &mut Vec<f64>| 1e3 * median(values);
        let [simulation, placement, whole] = &mut samples;
        println!(
            "| {guides} × {followers} × 24 | {} | {:.2} | {:.2} | {:.2} |",
            guides * (1 + followers),
            median_ms(simulation),
            median_ms(placement),
            median_ms(whole)
        );
    }
}

/// What gravity preloading costs when a groom is grown: 1 000 combed strands (the default groom) on a
/// skull collider, one thread, the supports found as the plugin finds them; the fastest of 5 runs.
fn preload_cost() {
    use bevy_hair_sim::rod::{ColliderShape, RodMaterial};
    println!();
    println!("| strands × edges | ms per 1 000 strands, preload (supports included) | µs per strand |");
    println!("|---|---:|---:|");
    for segments in [16, 24, 32] {
        let groom = HairGroom { strand_count: 1000, segments, ..HairGroom::default() };
        let skull = ColliderShape::Ellipsoid { semi_axes: groom.scalp.semi_axes.as_dvec3() };
        let reach = 40e-6 + 1e-3 + f64::from(bevy_hair_sim::simulation::PRELOAD_SUPPORT_DISTANCE);
        let rods: Vec<Rod> = groom
            .grow()
            .unwrap()
            .iter()
            .map(|strand| {
                let nodes: Vec<DVec3> = strand.nodes.iter().map(|node| node.as_dvec3()).collect();
                Rod::new(&nodes, strand.material_direction.as_dvec3(), RodMaterial::human_hair()).unwrap()
            })
            .collect();
        let fastest = (0..5)
            .map(|_| {
                let mut rods = rods.clone();
                let started = Instant::now();
                for rod in &mut rods {
                    let supports: Vec<Option<DVec3>> = rod
                        .positions()
                        .iter()
                        .map(|&node| {
                            skull.inflated(reach).contains(node).then(|| skull.closest_surface_point(node).normal)
                        })
                        .collect();
                    rod.preload_for_gravity(DVec3::new(0.0, -9.81, 0.0), &supports, 1.0).unwrap();
                }
                started.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min);
        println!("| 1 000 × {segments} | {:.2} | {:.2} |", 1e3 * fastest, 1e3 * fastest);
    }
}

/// Cost against strands and edges, with the ratio to the row with half as many.
fn scaling(threads: usize, steps: usize) {
    println!();
    println!("| strands | edges | ms / step | M node-steps / s | × previous strands | × previous edges |");
    println!("|---:|---:|---:|---:|---:|---:|");
    let strand_counts = [1, 100, 1000, 2000, 4000];
    let mut previous_edges = [None; 5];
    for edges in [16, 32, 64] {
        let mut previous_strands: Option<f64> = None;
        for (row, strands) in strand_counts.into_iter().enumerate() {
            let seconds = median_step_seconds(strands, edges, 0, threads, steps);
            let node_steps = (strands * (edges + 1)) as f64 / seconds;
            let ratio = |previous: Option<f64>| previous.map_or(String::new(), |p| format!("{:.2}", seconds / p));
            println!(
                "| {strands} | {edges} | {:.3} | {:.2} | {} | {} |",
                1e3 * seconds,
                1e-6 * node_steps,
                ratio(previous_strands),
                ratio(previous_edges[row])
            );
            previous_strands = Some(seconds);
            previous_edges[row] = Some(seconds);
        }
    }
}

/// One strand's step split into its parts (`RodWorkspace::time_parts`), in the mechanics core: 100 of
/// the scene's strands stepped one after another on one thread with the scene's head motion, without
/// and with the 10 cm skull as a collider.
fn parts_of_a_step(steps: usize) {
    let (strands, edges) = (100, 32);
    let roots = Scalp::default().roots(strands).expect("the default scalp holds 100 roots");
    let skull = MovingCollider::fixed(ColliderShape::sphere(0.1), 0.4, RigidPose::default());
    println!();
    println!("One strand's step in parts ({edges} edges, mean of {strands} strands × {steps} steps, one thread):");
    println!("| part | µs, no collider | share | µs, on the skull | share |");
    println!("|---|---:|---:|---:|---:|");
    let runs = [false, true].map(|with_skull| {
        let mut workspace = RodWorkspace::default();
        let (mut newton_iterations, mut projection_iterations) = (0u64, 0u64);
        let (mut rods, anchors, material_directions) = scene_strands(&roots, edges);
        let mut skull = skull.clone();
        for step in 0..WARM_UP_STEPS + steps {
            if step == WARM_UP_STEPS {
                workspace.time_parts(true);
            }
            let pose = |step: usize| {
                let (translation, rotation) = Scene::head_pose(step);
                RigidPose::new(rotation.as_dquat(), translation.as_dvec3())
            };
            (skull.start, skull.end) = (pose(step), pose(step + 1));
            let head = skull.end;
            let colliders = std::slice::from_ref(&skull);
            let contacts = Contacts { colliders: if with_skull { colliders } else { &[] }, thickness: 1e-3 };
            for ((rod, anchor), direction) in rods.iter_mut().zip(&anchors).zip(&material_directions) {
                clamp_on_head(rod, head, anchor, *direction);
                let report = rod
                    .step_with_contacts(&StepParams::default(), None, &contacts, &mut workspace)
                    .expect("a stable step");
                if step >= WARM_UP_STEPS {
                    newton_iterations += u64::from(report.newton_iterations);
                    projection_iterations += u64::from(report.projection_iterations);
                }
            }
        }
        let strand_steps = (strands * steps) as f64;
        let iterations = [newton_iterations, projection_iterations].map(|count| count as f64 / strand_steps);
        (*workspace.part_timings().expect("timing is on"), iterations)
    });
    let timings = runs.map(|(timings, _)| timings);
    let per_step =
        |time: std::time::Duration, timings: &StepTimings| 1e6 * time.as_secs_f64() / f64::from(timings.steps);
    for index in 0..5 {
        let row = timings.map(|timings| {
            let (name, time) = timings.parts()[index];
            (name, per_step(time, &timings), time.as_secs_f64() / timings.total().as_secs_f64())
        });
        println!(
            "| {} | {:.2} | {:.0} % | {:.2} | {:.0} % |",
            row[0].0,
            row[0].1,
            100.0 * row[0].2,
            row[1].1,
            100.0 * row[1].2
        );
    }
    let totals = timings.map(|timings| per_step(timings.total(), &timings));
    println!("| whole step | {:.2} | 100 % | {:.2} | 100 % |", totals[0], totals[1]);
    let [(_, without), (_, with)] = runs;
    println!("| Newton iterations per step | {:.2} | | {:.2} | |", without[0], with[0]);
    println!("| projection iterations per step | {:.2} | | {:.2} | |", without[1], with[1]);
}

/// The scene's straight strands of `edges` edges on `roots`, in the mechanics core, with each one's
/// root edge and material direction on the head at rest (to clamp them with [`clamp_on_head`]).
#[allow(clippy::type_complexity)]
fn scene_strands(roots: &[ScalpRoot], edges: usize) -> (Vec<Rod>, Vec<[DVec3; 2]>, Vec<DVec3>) {
    let rods: Vec<Rod> = roots
        .iter()
        .map(|root| {
            let (root, normal) = (root.position.as_dvec3(), root.normal.as_dvec3());
            let nodes: Vec<DVec3> =
                (0..=edges).map(|node| root + normal * f64::from(HAIR_LENGTH) * node as f64 / edges as f64).collect();
            Rod::new(&nodes, normal.any_orthonormal_vector(), RodMaterial::human_hair()).expect("a valid strand")
        })
        .collect();
    let anchors = rods.iter().map(|rod| [rod.positions()[0], rod.positions()[1]]).collect();
    let material_directions = rods.iter().map(|rod| rod.material_frame(0).m1).collect();
    (rods, anchors, material_directions)
}

/// Clamps a strand's root edge (`anchor`, on the head at rest) and material direction to the head at `head`.
fn clamp_on_head(rod: &mut Rod, head: RigidPose, anchor: &[DVec3; 2], material_direction: DVec3) {
    let [root, next] = anchor.map(|point| head.to_world(point));
    rod.clamp_edge(0, root, next, head.rotation * material_direction).expect("a valid clamp");
}

/// The mechanics core's step of the scene's 2 000 strands × 32 edges (no collider) on `threads`
/// threads, one strand at a time and [`LANES`] at a time in lockstep ([`LockstepWorkspace`]), stepped
/// in turn on copies of the same hair: the median wall time per step of each, and their ratio. The
/// two end bit for bit in the same place, which this checks.
fn lockstep(threads: usize, steps: usize) {
    let (strands, edges) = (2000, 32);
    let roots = Scalp::default().roots(strands).expect("the default scalp holds 2 000 roots");
    let (rods, anchors, material_directions) = scene_strands(&roots, edges);
    let mut copies = [rods.clone(), rods];
    let chunk = strands.div_ceil(threads).next_multiple_of(LANES);
    let params = StepParams::default();
    let mut times = [Vec::new(), Vec::new()];
    let mut workspaces: Vec<(RodWorkspace, LockstepWorkspace)> = (0..threads).map(|_| Default::default()).collect();
    for step in 0..WARM_UP_STEPS + steps {
        let (translation, rotation) = Scene::head_pose(step + 1);
        let head = RigidPose::new(rotation.as_dquat(), translation.as_dvec3());
        for (path, rods) in copies.iter_mut().enumerate() {
            let started = Instant::now();
            std::thread::scope(|scope| {
                let parts = rods.chunks_mut(chunk).zip(anchors.chunks(chunk)).zip(material_directions.chunks(chunk));
                for (((rods, anchors), directions), (workspace, lockstep_workspace)) in parts.zip(&mut workspaces) {
                    scope.spawn(move || {
                        for ((rod, anchor), direction) in rods.iter_mut().zip(anchors).zip(directions) {
                            clamp_on_head(rod, head, anchor, *direction);
                        }
                        if path == 0 {
                            for rod in rods {
                                rod.step(&params, None, workspace).expect("a stable step");
                            }
                        } else {
                            for batch in rods.chunks_mut(LANES) {
                                let mut strands = batch.iter_mut().map(|rod| LockstepStrand {
                                    rod,
                                    loads: StepLoads::default(),
                                    contacts: Contacts::NONE,
                                });
                                let mut strands: [LockstepStrand; LANES] =
                                    std::array::from_fn(|_| strands.next().expect("whole batches"));
                                for result in lockstep_workspace.step(&params, &mut strands).into_iter().flatten() {
                                    result.expect("a stable step");
                                }
                            }
                        }
                    });
                }
            });
            if step >= WARM_UP_STEPS {
                times[path].push(started.elapsed().as_secs_f64());
            }
        }
    }
    let same = copies[0].iter().zip(&copies[1]).all(|(a, b)| a.positions() == b.positions());
    assert!(same, "the lockstep batches ended where the strands alone did");
    let [alone, batched] = times.map(|mut times| median(&mut times));
    println!();
    println!(
        "The core's step of {strands} strands × {edges} edges on {threads} threads, alone and in lockstep, stepped in turn:"
    );
    println!("| path | ms / step | time × alone |");
    println!("|---|---:|---:|");
    println!("| one strand at a time | {:.3} | 1.00 |", 1e3 * alone);
    println!("| {LANES} strands in lockstep | {:.3} | {:.2} |", 1e3 * batched, batched / alone);
}

/// Cost against strands and colliders (skull, face, neck, shoulders, torso), 32 edges: the collision
/// share is the extra time over the same scene with no colliders, stepped in turn with it.
fn collisions(threads: usize, steps: usize) {
    const COLLIDER_COUNTS: [usize; 3] = [0, 1, 5];
    println!();
    println!("Collisions, 32 edges, colliders: skull, face, neck, shoulders, torso in that order:");
    println!("| strands | colliders | ms / step | collision share of the step | µs per strand |");
    println!("|---:|---:|---:|---:|---:|");
    for strands in [500, 1000, 2000] {
        let mut scenes =
            COLLIDER_COUNTS.map(|colliders| Scene::new(strands, 32, Some(threads)).with_colliders(colliders));
        let seconds = interleaved_median_step_seconds(&mut scenes, steps);
        let without = seconds[0];
        for (colliders, seconds) in COLLIDER_COUNTS.into_iter().zip(seconds) {
            let extra = seconds - without;
            println!(
                "| {strands} | {colliders} | {:.3} | {:.0} % | {:.2} |",
                1e3 * seconds,
                100.0 * extra / seconds,
                1e6 * extra / strands as f64
            );
        }
    }
}

/// One compute thread against one per core, each in a process of its own.
fn parallel_efficiency(cores: usize, quick: bool) {
    let run = |threads: usize| -> f64 {
        let mut command = Command::new(std::env::current_exe().expect("the benchmark's own path"));
        command.args(["measure", "2000", "32", "--threads", &threads.to_string()]);
        if quick {
            command.arg("--quick");
        }
        let output = command.output().expect("the benchmark runs itself");
        String::from_utf8_lossy(&output.stdout).trim().parse().expect("a time in seconds")
    };
    let one = run(1);
    let all = run(cores);
    println!();
    println!("Parallel efficiency, 2 000 strands × 32 edges:");
    println!("| compute threads | ms / step | speed-up |");
    println!("|---:|---:|---:|");
    println!("| 1 | {:.2} | 1.00 |", 1e3 * one);
    println!("| {cores} | {:.2} | {:.2} |", 1e3 * all, one / all);
}

/// Heap bytes per simulated node: everything the plugin keeps for 2 000 strands × 32 edges (rods,
/// solver workspaces, drawn poses, forces, entities), over their node count.
fn memory_per_node(threads: usize) {
    let (strands, edges) = (2000, 32);
    let before = BYTES_IN_USE.load(Ordering::Relaxed);
    let mut empty = Scene::new(0, edges, Some(threads));
    empty.step();
    empty.step();
    let without_hair = BYTES_IN_USE.load(Ordering::Relaxed) - before;
    drop(empty);
    let before = BYTES_IN_USE.load(Ordering::Relaxed);
    let mut scene = Scene::new(strands, edges, Some(threads));
    scene.step();
    scene.step();
    let with_hair = BYTES_IN_USE.load(Ordering::Relaxed) - before;
    let nodes = strands * (edges + 1);
    println!();
    println!("Memory, {strands} strands × {edges} edges ({nodes} nodes):");
    println!("| heap in use | bytes per node |");
    println!("|---:|---:|");
    println!(
        "| {:.1} MB | {:.0} |",
        1e-6 * (with_hair - without_hair) as f64,
        (with_hair - without_hair) as f64 / nodes as f64
    );
}
