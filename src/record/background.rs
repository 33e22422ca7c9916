//! A recording on a thread of its own.
//!
//! The simulation's thread only copies each step's events into their owned form (the one the
//! `--detail auto` layer holds steps in, [`HeldStep`]) and hands them over in batches; the
//! sink itself (for the `.rrd`: building the columns, the drawing, logging to the Rerun SDK)
//! runs on its own thread beside the simulation and sees the same events in the same order,
//! so it writes the same file. Emptied batches come back for reuse, and at most
//! [`QUEUED`] batches wait for the thread: a sink slower than the simulation holds the run
//! back instead of buffering without bound. The sink is finished on its thread too.

use super::auto::HeldStep;
use super::{Finished, RecordError, Recording};
use crate::events::{Event, Observer, RodInfo, RunInfo};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, SyncSender};
use std::sync::Arc;

/// Steps per batch.
const BATCH_STEPS: usize = 32;
/// Batches waiting for the thread at most (512 steps): enough for the run to go on while a
/// sink made on its thread sets up ([`Background::spawn`]; the `.rrd`'s setup takes as long
/// as a few hundred steps of the two-prong grasp).
const QUEUED: usize = 16;

/// Run the calling thread as a writer beside the simulation: on Linux `SCHED_BATCH`, the
/// policy for CPU-bound work that nobody waits on interactively. Such a thread gets its fair
/// share of the cores, but when it wakes (a batch arrived) it does not preempt the thread
/// running on the core it wakes on, so the simulation keeps its core (and its caches) until
/// its time slice ends instead of being switched out at every hand-over. Threads the calling
/// thread starts afterwards (the Rerun SDK's, when the `.rrd` sink is made here) inherit it.
/// Two-prong grasp, both files at step detail, 22 alternated rounds: wall time −6 to −8 %,
/// CPU time −5 % (docs/performance.md, "Recording cost"). Elsewhere, and if the call fails
/// (a policy the system refuses), the thread runs as it was.
pub fn as_writer_thread() {
    #[cfg(target_os = "linux")]
    {
        let p = libc::sched_param { sched_priority: 0 };
        // SAFETY: `p` is a valid `sched_param` for the call; pid 0 is the calling thread; the
        // call changes only its scheduling policy, and a failure leaves it as it was.
        unsafe { libc::sched_setscheduler(0, libc::SCHED_BATCH, &p) };
    }
}

/// A [`RunInfo`] with its parts owned, to cross to the thread.
struct OwnedRunInfo {
    dimension: u8,
    scenario_name: String,
    scenario_text: String,
    rods: Vec<RodInfo>,
    obstacles: Vec<crate::obstacle::Obstacle>,
    /// The 3D scene's shapes (`dimension` 3; `obstacles` is then empty).
    shapes: Vec<crate::rod3d::events::Shape3Info>,
    obstacle_names: Vec<String>,
    bodies: Vec<crate::world::body::BodySpec>,
    mode: crate::scenario::Mode,
}

impl OwnedRunInfo {
    fn new(i: &RunInfo<'_>) -> Self {
        let shapes = match i.scene {
            crate::events::Scene::Spatial { shapes } => shapes.to_vec(),
            crate::events::Scene::Planar { .. } => Vec::new(),
        };
        Self {
            dimension: i.dimension,
            shapes,
            scenario_name: i.scenario_name.to_string(),
            scenario_text: i.scenario_text.to_string(),
            rods: i.rods.to_vec(),
            obstacles: i.planar_obstacles().to_vec(),
            obstacle_names: i.obstacle_names.to_vec(),
            bodies: i.bodies.to_vec(),
            mode: i.mode,
        }
    }

    fn view(&self) -> RunInfo<'_> {
        let scene = if self.dimension == 3 {
            crate::events::Scene::Spatial {
                shapes: &self.shapes,
            }
        } else {
            crate::events::Scene::Planar {
                obstacles: &self.obstacles,
            }
        };
        RunInfo {
            dimension: self.dimension,
            scene,
            scenario_name: &self.scenario_name,
            scenario_text: &self.scenario_text,
            rods: &self.rods,
            obstacle_names: &self.obstacle_names,
            bodies: &self.bodies,
            mode: self.mode,
        }
    }
}

enum Msg {
    Start(Box<OwnedRunInfo>),
    /// The first `n` steps of the batch.
    Steps(Vec<HeldStep>, usize),
    End {
        steps: u64,
        t: f64,
        error: Option<String>,
    },
    Finish,
}

type Sink = Box<dyn Recording + Send>;

/// Makes a sink on its thread ([`Background::spawn`]).
pub type MakeSink = Box<dyn FnOnce() -> Result<Sink, RecordError> + Send>;

/// A [`Recording`] run on its own thread (see the module's text).
pub struct Background {
    format: &'static str,
    /// The sink's file (for errors).
    path: std::path::PathBuf,
    iterations: bool,
    /// The sink's failure flag; set here too when the thread stopped.
    failure: Arc<AtomicBool>,
    /// The batch being filled: `used` whole steps, then the step under way.
    batch: Vec<HeldStep>,
    used: usize,
    free: Vec<Vec<HeldStep>>,
    to: Option<SyncSender<Msg>>,
    back: Receiver<Vec<HeldStep>>,
    thread: Option<std::thread::JoinHandle<Option<Result<Finished, RecordError>>>>,
    /// Why the thread could not be reached, once it could not.
    lost: Option<String>,
}

impl Background {
    /// Start `sink`, which writes `path`, on a thread named `name`.
    pub fn start(sink: Sink, path: &Path, name: &str) -> Result<Self, RecordError> {
        let format = sink.format();
        let iterations = sink.wants_iterations();
        let failure = sink.failure().unwrap_or_default();
        Self::launch(
            format,
            iterations,
            failure,
            path,
            name,
            Box::new(move || Ok(sink)),
        )
    }

    /// Start a sink that `make` makes on the thread itself, so that its setup runs beside the
    /// run instead of before it (the `.rrd`'s: the Rerun SDK's stream and the blueprint, some
    /// milliseconds). `format` and `iterations` are what the sink will say it is and wants. A
    /// sink that cannot be made fails the recording: the run stops at its next step, the
    /// batches are taken and dropped, and [`Recording::finish`] returns the error.
    pub fn spawn(
        format: &'static str,
        iterations: bool,
        path: &Path,
        name: &str,
        make: MakeSink,
    ) -> Result<Self, RecordError> {
        Self::launch(format, iterations, Arc::default(), path, name, make)
    }

    fn launch(
        format: &'static str,
        iterations: bool,
        failure: Arc<AtomicBool>,
        path: &Path,
        name: &str,
        make: MakeSink,
    ) -> Result<Self, RecordError> {
        let (to, rx) = std::sync::mpsc::sync_channel(QUEUED);
        let (back_tx, back) = std::sync::mpsc::channel();
        let flag = failure.clone();
        let thread = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || serve(make, flag, rx, back_tx))
            .map_err(|source| RecordError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        Ok(Self {
            format,
            path: path.to_path_buf(),
            iterations,
            failure,
            batch: Vec::new(),
            used: 0,
            free: Vec::new(),
            to: Some(to),
            back,
            thread: Some(thread),
            lost: None,
        })
    }

    fn send(&mut self, msg: Msg) {
        let Some(to) = self.to.as_ref() else {
            return;
        };
        if to.send(msg).is_err() {
            self.lost = Some(format!("the {} thread stopped", self.format));
            self.failure.store(true, Ordering::Relaxed);
            self.to = None;
        }
    }

    /// Hand over the batch (its whole steps and the one under way when `partial`).
    fn send_batch(&mut self, partial: bool) {
        let under_way = self.batch.get(self.used).is_some_and(|s| !s.is_empty());
        let n = self.used + usize::from(partial && under_way);
        if n == 0 {
            return;
        }
        while let Ok(b) = self.back.try_recv() {
            self.free.push(b);
        }
        let next = self.free.pop().unwrap_or_default();
        let full = std::mem::replace(&mut self.batch, next);
        self.used = 0;
        self.send(Msg::Steps(full, n));
    }

    /// The step under way (a cleared slot of the batch).
    fn current(&mut self) -> &mut HeldStep {
        if self.used == self.batch.len() {
            self.batch.push(HeldStep::default());
        }
        &mut self.batch[self.used]
    }
}

/// The thread: make the sink, replay every event into it, in order (the sink's failure flag
/// passed on to the run's after each message), and finish it when told.
fn serve(
    make: MakeSink,
    failure: Arc<AtomicBool>,
    rx: Receiver<Msg>,
    back: Sender<Vec<HeldStep>>,
) -> Option<Result<Finished, RecordError>> {
    as_writer_thread();
    let mut sink = match make() {
        Ok(sink) => sink,
        Err(e) => {
            failure.store(true, Ordering::Relaxed);
            for msg in rx {
                match msg {
                    Msg::Steps(mut steps, _) => {
                        steps.iter_mut().for_each(HeldStep::clear);
                        let _ = back.send(steps);
                    }
                    Msg::Finish => return Some(Err(e)),
                    _ => {}
                }
            }
            return None;
        }
    };
    let own = sink.failure();
    for msg in rx {
        match msg {
            Msg::Start(info) => sink.on_event(&Event::RunStart(&info.view())),
            Msg::Steps(mut steps, n) => {
                for s in &mut steps[..n] {
                    s.send(sink.as_mut(), true);
                    s.clear();
                }
                let _ = back.send(steps);
            }
            Msg::End { steps, t, error } => sink.on_event(&Event::RunEnd {
                steps,
                t,
                error: error.as_deref(),
            }),
            Msg::Finish => return Some(sink.finish()),
        }
        if own.as_ref().is_some_and(|f| f.load(Ordering::Relaxed)) {
            failure.store(true, Ordering::Relaxed);
        }
    }
    None
}

impl Observer for Background {
    fn wants_iterations(&self) -> bool {
        self.iterations
    }

    fn on_event(&mut self, event: &Event<'_>) {
        match *event {
            Event::RunStart(info) => {
                self.send_batch(true);
                self.send(Msg::Start(Box::new(OwnedRunInfo::new(info))));
            }
            Event::RunEnd { steps, t, error } => {
                self.send_batch(true);
                self.send(Msg::End {
                    steps,
                    t,
                    error: error.map(str::to_string),
                });
            }
            Event::Iteration { .. } if !self.iterations => {}
            Event::StepEnd { .. } => {
                self.current().keep(event);
                self.used += 1;
                if self.used >= BATCH_STEPS {
                    self.send_batch(false);
                }
            }
            _ => {
                self.current().keep(event);
            }
        }
    }
}

impl Recording for Background {
    fn format(&self) -> &'static str {
        self.format
    }

    fn finish(&mut self) -> Result<Finished, RecordError> {
        self.send_batch(true);
        self.send(Msg::Finish);
        self.to = None;
        let joined = self.thread.take().map(|t| t.join());
        match joined {
            Some(Ok(Some(result))) => result,
            _ => Err(RecordError::write(
                &self.path,
                self.lost
                    .clone()
                    .unwrap_or_else(|| format!("the {} thread stopped", self.format)),
            )),
        }
    }

    fn failure(&self) -> Option<Arc<AtomicBool>> {
        Some(self.failure.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::events::Fanout;
    use std::sync::Mutex;

    /// Writes every event it sees, in its `Debug` form, to a shared log.
    struct Log {
        lines: Arc<Mutex<Vec<String>>>,
        iterations: bool,
        failure: Arc<AtomicBool>,
    }

    impl Observer for Log {
        fn wants_iterations(&self) -> bool {
            self.iterations
        }
        fn on_event(&mut self, event: &Event<'_>) {
            let line = match event {
                // The run's facts: the scenario's name and rods are enough to tell.
                Event::RunStart(i) => format!("start {} {:?}", i.scenario_name, i.rods),
                e => format!("{e:?}"),
            };
            self.lines.lock().unwrap().push(line);
        }
    }

    impl Recording for Log {
        fn format(&self) -> &'static str {
            "log"
        }
        fn finish(&mut self) -> Result<Finished, RecordError> {
            self.lines.lock().unwrap().push("finished".into());
            Ok(Finished {
                path: "log".into(),
                complete: true,
            })
        }
        fn failure(&self) -> Option<Arc<AtomicBool>> {
            Some(self.failure.clone())
        }
    }

    fn log(iterations: bool) -> (Log, Arc<Mutex<Vec<String>>>) {
        let lines = Arc::new(Mutex::new(Vec::new()));
        let sink = Log {
            lines: lines.clone(),
            iterations,
            failure: Arc::default(),
        };
        (sink, lines)
    }

    /// A sink behind [`Background`] sees every event the run sends, in order, also the
    /// Newton iterations, over many batches: the same lines as the same sink in the run's
    /// thread; it is finished on its thread, and its failure flag is the wrapper's.
    #[test]
    fn the_sink_on_its_thread_sees_what_the_run_sends() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/two-prong-grasp.toml");
        for iterations in [false, true] {
            // 600 steps: more than BATCH_STEPS x QUEUED.
            let sc = crate::Scenario::load(&path, &["solve.t_end=0.006".into()]).unwrap();
            let (mut direct, seen_here) = log(iterations);
            let (behind, seen_there) = log(iterations);
            let flag = behind.failure.clone();
            let mut bg =
                Background::start(Box::new(behind), Path::new("log"), "test-sink").unwrap();
            assert_eq!(bg.wants_iterations(), iterations);
            {
                let mut fan = Fanout::new();
                fan.push(&mut direct as &mut dyn Observer);
                fan.push(&mut bg as &mut dyn Observer);
                crate::Simulation::new(&sc).run(&mut fan).unwrap();
            }
            let done = bg.finish().unwrap();
            assert!(done.complete);
            let here = seen_here.lock().unwrap().clone();
            let there = seen_there.lock().unwrap().clone();
            assert_eq!(there.last().map(String::as_str), Some("finished"));
            assert_eq!(here, there[..there.len() - 1], "iterations: {iterations}");
            let steps = here.iter().filter(|l| l.starts_with("StepEnd")).count();
            assert_eq!(steps, 601, "the initial state and 600 steps");
            let its = here.iter().filter(|l| l.starts_with("Iteration")).count();
            assert_eq!(its > 0, iterations);
            flag.store(true, Ordering::Relaxed);
            assert!(bg.failure().unwrap().load(Ordering::Relaxed));
        }
    }

    /// A sink made on its thread ([`Background::spawn`]) sees what the run sends, and its
    /// failure flag reaches the run's; one that cannot be made fails the recording without
    /// holding the run back, and `finish` says why.
    #[test]
    fn a_sink_made_on_its_thread_sees_the_run_or_fails_it() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/two-prong-grasp.toml");
        let sc = crate::Scenario::load(&path, &["solve.t_end=0.006".into()]).unwrap();
        let (mut direct, seen_here) = log(false);
        let (behind, seen_there) = log(false);
        // The sink fails (its own flag) once made: the wrapper's flag follows.
        behind.failure.store(true, Ordering::Relaxed);
        let make: MakeSink = Box::new(move || Ok(Box::new(behind)));
        let mut bg = Background::spawn("log", false, Path::new("log"), "test-sink", make).unwrap();
        assert!(!bg.failure().unwrap().load(Ordering::Relaxed));
        {
            let mut fan = Fanout::new();
            fan.push(&mut direct as &mut dyn Observer);
            fan.push(&mut bg as &mut dyn Observer);
            crate::Simulation::new(&sc).run(&mut fan).unwrap();
        }
        assert!(bg.finish().unwrap().complete);
        assert!(bg.failure().unwrap().load(Ordering::Relaxed));
        let here = seen_here.lock().unwrap().clone();
        let there = seen_there.lock().unwrap().clone();
        assert_eq!(here, there[..there.len() - 1]);
        assert_eq!(
            here.iter().filter(|l| l.starts_with("StepEnd")).count(),
            601
        );

        let make: MakeSink = Box::new(|| Err(RecordError::write(Path::new("x.rrd"), "no way")));
        let mut bg = Background::spawn("log", true, Path::new("x.rrd"), "test-sink", make).unwrap();
        crate::Simulation::new(&sc).run(&mut bg).unwrap();
        assert!(bg.failure().unwrap().load(Ordering::Relaxed));
        let e = bg.finish().unwrap_err().to_string();
        assert!(e.contains("x.rrd") && e.contains("no way"), "{e}");
    }

    /// The sink's thread runs as a writer (`SCHED_BATCH`), and so do the threads it starts
    /// (the Rerun SDK's, when the `.rrd` sink is made there); the run's thread keeps its
    /// policy.
    #[cfg(target_os = "linux")]
    #[test]
    fn the_sink_thread_runs_as_a_writer_and_the_run_does_not() {
        struct Policy(Arc<Mutex<Vec<i32>>>);
        impl Observer for Policy {
            fn on_event(&mut self, event: &Event<'_>) {
                if let Event::RunStart(_) = event {
                    // SAFETY: no arguments but the calling thread (0).
                    let here = unsafe { libc::sched_getscheduler(0) };
                    let child = std::thread::spawn(|| unsafe { libc::sched_getscheduler(0) })
                        .join()
                        .unwrap();
                    self.0.lock().unwrap().extend([here, child]);
                }
            }
        }
        impl Recording for Policy {
            fn format(&self) -> &'static str {
                "policy"
            }
            fn finish(&mut self) -> Result<Finished, RecordError> {
                Ok(Finished {
                    path: "policy".into(),
                    complete: true,
                })
            }
        }
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/two-prong-grasp.toml");
        let sc = crate::Scenario::load(&path, &["solve.t_end=0.0005".into()]).unwrap();
        // SAFETY: as above.
        let before = unsafe { libc::sched_getscheduler(0) };
        assert_ne!(before, libc::SCHED_BATCH);
        let seen = Arc::new(Mutex::new(Vec::new()));
        let sink = Policy(seen.clone());
        let mut bg = Background::start(Box::new(sink), Path::new("policy"), "test-sink").unwrap();
        crate::Simulation::new(&sc).run(&mut bg).unwrap();
        bg.finish().unwrap();
        assert_eq!(*seen.lock().unwrap(), [libc::SCHED_BATCH; 2]);
        assert_eq!(unsafe { libc::sched_getscheduler(0) }, before);
    }
}
