//! What recording costs: a scenario (default two-prong-grasp, the one the recording targets
//! of docs/performance.md are stated for) run with no sink, with no sink beside a thread
//! spinning on the other core (the simulation at the clock the recorded rows, which keep both
//! cores busy, run it at; its CPU time includes the spinning thread's), with each sink
//! alone, with .rrd + .mcap at step detail, at iteration detail, and at `--detail auto` (the
//! default of `gripsim run`: the decimating layer in front of both files, with its live spike
//! detector at the default thresholds; the survey run that picks the drawing scale is not
//! part of any row).
//!
//!     cargo bench --bench recording_cost [-- REPEATS] [SCENARIO]
//!
//! SCENARIO is a name under scenarios/ (`two-prong-grasp`) or a path to a .toml file.
//! `RECORDING_COST_ROWS=mcap` runs only the rows whose name contains `mcap` (and the row
//! without sinks, the reference of the ratios), e.g. to profile one sink under `perf`.
//! `RECORDING_COST_FLUSH_EVERY=N` overrides the scenario's `[output] flush_every` (the steps
//! per `.rrd` chunk and MCAP chunk). `RECORDING_COST_ZSTD=N` sets the MCAP's zstd level (its
//! min match and hash log stay the sink's) and `RECORDING_COST_PRECISION=f64` its /sim/step
//! precision (defaults: the sink's, -1 and f32).
//! `RECORDING_COST_RRD_THREAD=off` runs the `.rrd` sink in the run's thread instead of on a
//! thread of its own (as `gripsim run` does), to compare the two.
//! Prints a Markdown table for docs/performance.md: the median wall time of REPEATS runs
//! (default 7; the rows are run round-robin, the k-th run of every row before the (k+1)-th of
//! any, so a slow stretch of the machine falls on all rows alike) and the median of its part
//! after the last step (finishing the files: the writer threads' backlog, closing), the mean CPU time of the
//! process per run (all threads, from /proc/self/stat, summed over the row's runs;
//! steadier than wall time on a busy machine), their ratios to the run without sinks, the
//! median CPU time of the thread that runs the simulation and the sinks' parts that run
//! there (the `.rrd` sink runs on a thread of its own, as in `gripsim run`; the rest is the
//! sinks' threads: the wall time cannot drop below it), the
//! file sizes and the bytes on disk per node-step (all files of the row together, over
//! (steps + 1) × nodes: every recorded step holds the initial state too). Below the table:
//! the no-sink runs by the core they ran on, and their medians (cores of a shared VM can
//! differ in speed, and the reference runs on one of them).

use gripsim::events::{Fanout, NullObserver, Observer};
use gripsim::record::auto::AutoDetail;
use gripsim::record::background::{Background, MakeSink};
use gripsim::record::csv::CsvSink;
use gripsim::record::mcap::McapSink;
use gripsim::record::rerun::RerunSink;
use gripsim::record::{AutoRule, Detail, RecordOptions, Recording};
use gripsim::{Scenario, Simulation};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Clone, Copy)]
struct Case {
    name: &'static str,
    rrd: bool,
    mcap: bool,
    csv: bool,
    detail: Detail,
    /// A thread spinning beside the run (no sink): the simulation at the clock it gets while
    /// the other core works, as in the recorded rows.
    busy: bool,
}

/// One run; returns the wall time (s), the part of it spent finishing the files (after the
/// last step: the writer threads' backlog, closing, `fsync`) and the sizes of the files
/// written.
fn run(sc: &Scenario, case: Case, dir: &Path) -> (f64, f64, Vec<(&'static str, u64)>) {
    let detail = match case.detail {
        Detail::Auto(r) if r.every == 0 => Detail::Auto(AutoRule::for_scenario(sc)),
        d => d,
    };
    let opts = RecordOptions {
        detail,
        flush_every: sc.flush_every,
    };
    let start = Instant::now();
    let mut sim = Simulation::new(sc);
    let mut sinks: Vec<Box<dyn Recording>> = Vec::new();
    if case.rrd {
        // As `gripsim run` does: the `.rrd` sink on a thread of its own
        // (`RECORDING_COST_RRD_THREAD=off`: in the run's thread, to compare).
        let path = dir.join("bench.rrd");
        if std::env::var("RECORDING_COST_RRD_THREAD").as_deref() != Ok("off") {
            // Made on its thread, beside the run (as `gripsim run` makes it beside the
            // survey).
            let (p, sc) = (path.clone(), sc.clone());
            let make: MakeSink = Box::new(move || Ok(Box::new(RerunSink::create(&p, opts, &sc)?)));
            sinks.push(Box::new(
                Background::spawn("rerun", detail.iterations(), &path, "rrd-sink", make).unwrap(),
            ));
        } else {
            sinks.push(Box::new(RerunSink::create(&path, opts, sc).unwrap()));
        }
    }
    if case.mcap {
        // `RECORDING_COST_ZSTD=N`: the MCAP's zstd level (default: the sink's, -1; its min
        // match and hash log stay);
        // `RECORDING_COST_PRECISION=f64`: exact doubles in /sim/step.
        let mut mcap = gripsim::record::mcap::McapOptions::default();
        if let Some(l) = std::env::var("RECORDING_COST_ZSTD")
            .ok()
            .and_then(|v| v.parse::<i32>().ok())
        {
            mcap.zstd_level = l;
        }
        if std::env::var("RECORDING_COST_PRECISION").as_deref() == Ok("f64") {
            mcap.precision = gripsim::scenario::Precision::F64;
        }
        sinks.push(Box::new(
            McapSink::create_with(&dir.join("bench.mcap"), opts, mcap).unwrap(),
        ));
    }
    if case.csv {
        sinks.push(Box::new(
            CsvSink::create(&dir.join("bench.csv"), opts).unwrap(),
        ));
    }
    if sinks.is_empty() {
        let spin = case.busy.then(spin_beside);
        sim.run(&mut NullObserver).unwrap();
        if let Some((stop, thread)) = spin {
            stop.store(true, std::sync::atomic::Ordering::Relaxed);
            thread.join().unwrap();
        }
    } else {
        let mut fan = Fanout::new();
        for s in sinks.iter_mut() {
            fan.push(s.as_mut() as &mut dyn Observer);
        }
        match detail.auto() {
            Some(rule) => {
                let th = gripsim::replay::Thresholds::DEFAULT;
                let spikes = gripsim::replay::detect::Detector::new(sc, &th);
                let mut auto = AutoDetail::new(fan, rule, Some(spikes));
                sim.run(&mut auto).unwrap();
            }
            None => {
                sim.run(&mut fan).unwrap();
            }
        }
    }
    let finishing = Instant::now();
    let mut sizes = Vec::new();
    for s in sinks.iter_mut() {
        let f = s.finish().unwrap();
        sizes.push((s.format(), std::fs::metadata(&f.path).unwrap().len()));
    }
    (
        start.elapsed().as_secs_f64(),
        finishing.elapsed().as_secs_f64(),
        sizes,
    )
}

/// A thread that does integer work until told to stop (and its stop flag), started once it
/// runs.
fn spin_beside() -> (
    std::sync::Arc<std::sync::atomic::AtomicBool>,
    std::thread::JoinHandle<()>,
) {
    use std::sync::atomic::{AtomicBool, Ordering};
    let stop = std::sync::Arc::new(AtomicBool::new(false));
    let started = std::sync::Arc::new(std::sync::Barrier::new(2));
    let (s, b) = (stop.clone(), started.clone());
    let thread = std::thread::spawn(move || {
        b.wait();
        let mut x = 1u64;
        while !s.load(Ordering::Relaxed) {
            for _ in 0..1000 {
                x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
            }
        }
    });
    started.wait();
    (stop, thread)
}

/// The core this thread runs on now (Linux; None elsewhere or on error).
fn current_cpu() -> Option<usize> {
    // SAFETY: no arguments, no memory touched.
    let c = unsafe { libc::sched_getcpu() };
    usize::try_from(c).ok()
}

/// CPU time of this process so far (user + system, all threads, s); Linux only.
fn cpu_time() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) start at ") ".
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0) // USER_HZ
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let repeats: usize = args.iter().find_map(|a| a.parse().ok()).unwrap_or(7);
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    // cargo passes `--bench` to a bench without a harness: skip flags.
    let name = args
        .iter()
        .find(|a| a.parse::<usize>().is_err() && !a.starts_with('-'))
        .cloned()
        .unwrap_or_else(|| "two-prong-grasp".into());
    let path = if name.ends_with(".toml") {
        PathBuf::from(&name)
    } else {
        root.join("scenarios").join(format!("{name}.toml"))
    };
    let mut sc = Scenario::load(&path, &[]).unwrap();
    if let Some(n) = std::env::var("RECORDING_COST_FLUSH_EVERY")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        sc.flush_every = n;
    }
    let dir = match std::env::var_os("RECORDING_COST_KEEP") {
        Some(keep) => PathBuf::from(keep),
        None => std::env::temp_dir().join(format!("gripsim-bench-{}", std::process::id())),
    };
    std::fs::create_dir_all(&dir).unwrap();
    let step = Detail::Step;
    let cases = [
        Case {
            name: "no sink",
            rrd: false,
            mcap: false,
            csv: false,
            detail: step,
            busy: false,
        },
        Case {
            name: "no sink, other core busy",
            rrd: false,
            mcap: false,
            csv: false,
            detail: step,
            busy: true,
        },
        Case {
            name: ".rrd only, step detail",
            rrd: true,
            mcap: false,
            csv: false,
            detail: step,
            busy: false,
        },
        Case {
            name: ".mcap only, step detail",
            rrd: false,
            mcap: true,
            csv: false,
            detail: step,
            busy: false,
        },
        Case {
            name: ".csv only",
            rrd: false,
            mcap: false,
            csv: true,
            detail: step,
            busy: false,
        },
        Case {
            name: ".rrd + .mcap, step detail",
            rrd: true,
            mcap: true,
            csv: false,
            detail: step,
            busy: false,
        },
        Case {
            name: ".rrd + .mcap, iteration detail",
            rrd: true,
            mcap: true,
            csv: false,
            detail: Detail::Iteration,
            busy: false,
        },
        Case {
            name: ".rrd + .mcap, auto detail",
            rrd: true,
            mcap: true,
            csv: false,
            detail: Detail::Auto(AutoRule::default()),
            busy: false,
        },
    ];
    let steps = (sc.solve.t_end / sc.solve.dt).round();
    let nodes: usize = sc.rods.iter().map(|r| r.nodes).sum();
    let node_steps = (steps + 1.0) * nodes as f64;
    println!(
        "{} ({steps} steps, {nodes} nodes), median of {repeats} runs, flush every {} steps\n",
        sc.name, sc.flush_every
    );
    println!(
        "| sinks | wall time (s) | × no sink | of which finishing (s) | CPU time (s) | × no sink | run's thread CPU (s) | files | bytes per node-step |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---|---:|");
    let mut base = None;
    let mut cpu_base = None;
    let only = std::env::var("RECORDING_COST_ROWS").ok();
    let cases: Vec<Case> = cases
        .into_iter()
        .filter(|case| match &only {
            Some(o) => case.name.contains(o.as_str()) || case.name.starts_with("no sink"),
            None => true,
        })
        .collect();
    // Round-robin: the k-th run of every row before the (k+1)-th of any, so that a slow or
    // fast stretch of a shared machine (whose speed changes from minute to minute) falls on
    // all rows alike and the ratios to the no-sink row keep their meaning.
    let mut times = vec![Vec::new(); cases.len()];
    let mut cpus = vec![Some(0.0); cases.len()];
    let mut sizes = vec![Vec::new(); cases.len()];
    let mut own = vec![Vec::new(); cases.len()];
    let mut ends = vec![Vec::new(); cases.len()];
    let mut reference_cpus = std::collections::BTreeMap::new();
    for _ in 0..repeats {
        for (k, case) in cases.iter().enumerate() {
            let cpu0 = cpu_time();
            let own0 = gripsim::bench::thread_cpu_s();
            let on = current_cpu();
            let (t, end, s) = run(&sc, *case, &dir);
            if k == 0 {
                // The reference's core: the same at its start and end, or it moved.
                let cpu = on.filter(|&c| Some(c) == current_cpu());
                reference_cpus.entry(cpu).or_insert_with(Vec::new).push(t);
            }
            ends[k].push(end);
            own[k].push(gripsim::bench::thread_cpu_s() - own0);
            let used = cpu_time().zip(cpu0).map(|(b, a)| b - a);
            cpus[k] = cpus[k].zip(used).map(|(c, u)| c + u);
            times[k].push(t);
            sizes[k] = s;
        }
    }
    let mut medians = Vec::new();
    for (k, case) in cases.iter().enumerate() {
        let cpu = cpus[k].map(|c| c / repeats as f64);
        let times = &mut times[k];
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        medians.push((case.name, median));
        let base = *base.get_or_insert(median);
        own[k].sort_by(f64::total_cmp);
        let own = own[k][own[k].len() / 2];
        ends[k].sort_by(f64::total_cmp);
        let end = ends[k][ends[k].len() / 2];
        let cpu_text = match cpu {
            Some(c) => {
                let b = *cpu_base.get_or_insert(c.max(0.001));
                format!("{c:.3} | {:.0}", c / b)
            }
            None => "n/a | n/a".to_string(),
        };
        let files: Vec<String> = sizes[k]
            .iter()
            .map(|(f, n)| format!("{f} {:.1} MB", *n as f64 / 1e6))
            .collect();
        let bytes: u64 = sizes[k].iter().map(|(_, n)| n).sum();
        println!(
            "| {} | {median:.4} | {:.1} | {end:.4} | {cpu_text} | {own:.3} | {} | {} |",
            case.name,
            median / base,
            if files.is_empty() {
                "-".into()
            } else {
                files.join(", ")
            },
            if bytes == 0 {
                "-".into()
            } else {
                format!("{:.1}", bytes as f64 / node_steps)
            }
        );
    }
    // The recorded rows keep both cores busy: on a machine whose cores share a clock budget
    // (this VM, docs/performance.md, "Recording cost") the simulation in them runs at the
    // clock of the busy row, not at the one a single busy core gets.
    let median_of = |name: &str| medians.iter().find(|m| m.0 == name).map(|m| m.1);
    if let (Some(alone), Some(busy), Some(both)) = (
        median_of("no sink"),
        median_of("no sink, other core busy"),
        median_of(".rrd + .mcap, step detail"),
    ) {
        println!(
            "\nthe no-sink run with the other core busy: {busy:.4} s, {:.2}× its time alone; \
             .rrd + .mcap at step detail against it: {:.1}×",
            busy / alone,
            both / busy
        );
    }
    // The no-sink reference runs on one core, the recorded rows on all: on a machine whose
    // cores differ in speed (a shared VM's vCPUs), the ratios depend on which core the
    // reference got (docs/performance.md, "Recording cost").
    let by_cpu: Vec<String> = reference_cpus
        .iter_mut()
        .map(|(cpu, ts)| {
            ts.sort_by(f64::total_cmp);
            let at = cpu.map_or("moved".to_string(), |c| format!("cpu {c}"));
            format!("{at}: {} runs, median {:.4} s", ts.len(), ts[ts.len() / 2])
        })
        .collect();
    println!(
        "\nno-sink runs by core (the same at start and end): {}",
        by_cpu.join("; ")
    );
    // `RECORDING_COST_KEEP=DIR`: keep the last run's files of each row there (to look at
    // their bytes).
    match std::env::var_os("RECORDING_COST_KEEP") {
        Some(keep) => println!("\nfiles of the last row kept in {}", keep.to_string_lossy()),
        None => {
            std::fs::remove_dir_all(&dir).ok();
        }
    }
}
