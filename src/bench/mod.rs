//! `gripsim bench`: run time against error for each stepping strategy (work-precision), cost
//! per step against nodes (scaling), and a numerical stability stress map.

pub mod plot;

use crate::events::{Event, NullObserver, Observer};
use crate::record::summary::{Summary, SummaryCollector};
use crate::scenario::Scenario;
use crate::solver::Simulation;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The scenarios the bench uses, embedded so it runs from any folder.
pub const SEED_R5: &str = include_str!("../../scenarios/seed-grasp-r5.toml");
pub const TWO_PRONG: &str = include_str!("../../scenarios/two-prong-grasp.toml");
pub const DROP: &str = include_str!("../../recordings/golden/point-mass-plane-dt1e-4.toml");
pub const CANTILEVER: &str = include_str!("../../scenarios/cantilever-gravity.toml");

#[derive(Debug, Clone)]
pub struct BenchOptions {
    pub quick: bool,
    pub out: PathBuf,
    /// Timed runs per rung (the median is reported).
    pub repeats: usize,
}

/// A stepping strategy: the `--set` overrides that select it for a ladder parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Strategy {
    Fixed,
    Proximity,
    Adaptive,
    AdaptiveToi,
    /// The second-order integrator (BDF2), fixed dt.
    Bdf2Fixed,
    /// BDF2 under error control with time of impact.
    Bdf2AdaptiveToi,
    /// TR-BDF2 under error control with time of impact (the same rungs as BDF2's).
    TrBdf2AdaptiveToi,
}

/// Every strategy, in table order.
pub const STRATEGIES: [Strategy; 7] = [
    Strategy::Fixed,
    Strategy::Proximity,
    Strategy::Adaptive,
    Strategy::AdaptiveToi,
    Strategy::Bdf2Fixed,
    Strategy::Bdf2AdaptiveToi,
    Strategy::TrBdf2AdaptiveToi,
];

impl Strategy {
    pub fn name(self) -> &'static str {
        match self {
            Strategy::Fixed => "fixed",
            Strategy::Proximity => "proximity",
            Strategy::Adaptive => "adaptive",
            Strategy::AdaptiveToi => "adaptive+toi",
            Strategy::Bdf2Fixed => "bdf2",
            Strategy::Bdf2AdaptiveToi => "bdf2+adaptive+toi",
            Strategy::TrBdf2AdaptiveToi => "tr_bdf2+adaptive+toi",
        }
    }

    fn sets(self, p: f64) -> Vec<String> {
        match self {
            Strategy::Bdf2Fixed | Strategy::Bdf2AdaptiveToi => {
                let base = if self == Strategy::Bdf2Fixed {
                    Strategy::Fixed
                } else {
                    Strategy::AdaptiveToi
                };
                let mut v = base.sets(p);
                v.push("solve.integrator=\"bdf2\"".into());
                v
            }
            Strategy::TrBdf2AdaptiveToi => {
                let mut v = Strategy::AdaptiveToi.sets(p);
                v.push("solve.integrator=\"tr_bdf2\"".into());
                v
            }
            Strategy::Fixed => vec!["solve.stepping=\"fixed\"".into(), format!("solve.dt={p:e}")],
            Strategy::Proximity => vec![
                "solve.stepping=\"proximity\"".into(),
                format!("solve.dt={p:e}"),
                format!("solve.dt_near={:e}", p / 10.0),
                "solve.near_distance=1e-3".into(),
            ],
            Strategy::Adaptive | Strategy::AdaptiveToi => {
                let mut v = vec![
                    "solve.stepping=\"adaptive\"".into(),
                    format!("solve.rtol={p:e}"),
                    "solve.atol=1e-12".into(),
                    "solve.dt=1e-5".into(),
                    "solve.dt_min=1e-9".into(),
                    "solve.dt_max=1e-3".into(),
                ];
                if self == Strategy::AdaptiveToi {
                    v.push("solve.time_of_impact=true".into());
                }
                v
            }
        }
    }

    fn param_name(self) -> &'static str {
        match self {
            Strategy::Fixed | Strategy::Proximity | Strategy::Bdf2Fixed => "dt",
            _ => "rtol",
        }
    }
}

/// Samples every node's position at fixed times by linear interpolation between step ends.
pub struct Sampler {
    pub times: Vec<f64>,
    /// samples[k][rod] = positions at times[k]
    pub samples: Vec<Vec<Vec<f64>>>,
    prev: Option<(f64, Vec<Vec<f64>>)>,
    next: usize,
}

impl Sampler {
    pub fn new(t_end: f64, count: usize) -> Self {
        let times = (1..=count)
            .map(|k| t_end * k as f64 / count as f64)
            .collect();
        Self {
            times,
            samples: Vec::new(),
            prev: None,
            next: 0,
        }
    }
}

impl Observer for Sampler {
    fn on_event(&mut self, e: &Event<'_>) {
        if let Event::StepEnd { t, rods, .. } = e {
            let cur: Vec<Vec<f64>> = rods.iter().map(|r| r.q.to_vec()).collect();
            if let Some((t0, q0)) = &self.prev {
                while self.next < self.times.len() && self.times[self.next] <= *t + 1e-15 {
                    let ts = self.times[self.next];
                    let f = if *t > *t0 {
                        ((ts - t0) / (t - t0)).clamp(0.0, 1.0)
                    } else {
                        1.0
                    };
                    self.samples.push(
                        q0.iter()
                            .zip(&cur)
                            .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x + f * (y - x)).collect())
                            .collect(),
                    );
                    self.next += 1;
                }
            }
            self.prev = Some((*t, cur));
        }
    }
}

/// What one accuracy run measured.
#[derive(Debug, Clone)]
pub struct Measured {
    pub summary: Summary,
    pub samples: Vec<Vec<Vec<f64>>>,
}

fn load(text: &str, sets: &[String]) -> Result<Scenario, String> {
    Scenario::from_str(text, "<bench>", sets).map_err(|e| e.to_string())
}

/// Run once with a summary and a position sampler.
pub fn measure(text: &str, sets: &[String], samples: usize) -> Result<Measured, String> {
    let sc = load(text, sets)?;
    let mut sim = Simulation::new(&sc);
    let mut col = SummaryCollector::new();
    let mut smp = Sampler::new(sc.solve.t_end, samples);
    {
        let mut fan = crate::events::Fanout::new();
        fan.push(&mut col);
        fan.push(&mut smp);
        sim.run(&mut fan).map_err(|e| e.to_string())?;
    }
    Ok(Measured {
        summary: col.finish(&sim.stats, 0.0),
        samples: smp.samples,
    })
}

/// CPU time of the calling thread (s; NaN where the clock is unavailable). Unlike wall time
/// it leaves out the time other processes hold the cores, so it can be compared between runs
/// on a shared machine.
pub fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec into the one it is given.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if rc != 0 {
        return f64::NAN;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Median wall time (s) of `repeats` runs with no observer at all.
pub fn time_run(text: &str, sets: &[String], repeats: usize) -> Result<(f64, u64, u64), String> {
    time_run_cpu(text, sets, repeats).map(|(w, _, s, i)| (w, s, i))
}

/// Median wall time and median thread CPU time (s) of `repeats` runs with no observer, steps
/// and Newton iterations.
pub fn time_run_cpu(
    text: &str,
    sets: &[String],
    repeats: usize,
) -> Result<(f64, f64, u64, u64), String> {
    let sc = load(text, sets)?;
    let mut times = Vec::new();
    let mut cpu = Vec::new();
    let mut steps = 0;
    let mut iters = 0;
    for _ in 0..repeats.max(1) {
        let mut sim = Simulation::new(&sc);
        let (t0, c0) = (Instant::now(), thread_cpu_s());
        let stats = sim.run(&mut NullObserver).map_err(|e| e.to_string())?;
        times.push(t0.elapsed().as_secs_f64());
        cpu.push(thread_cpu_s() - c0);
        steps = stats.steps;
        iters = stats.newton_iterations;
    }
    times.sort_by(|a, b| a.total_cmp(b));
    cpu.sort_by(|a, b| a.total_cmp(b));
    Ok((times[times.len() / 2], cpu[cpu.len() / 2], steps, iters))
}

/// A timed sample of a short run is this many seconds of back-to-back runs at least (their
/// mean): a 1 ms run timed alone is at the mercy of one scheduler tick or one cache-cold
/// moment, and the work-precision verdict divides by the shortest runs.
pub const MIN_SAMPLE_S: f64 = 0.02;

/// [`time_run_cpu`] for several runs of one scene at once, timed round-robin: the k-th timed
/// sample of every set before the (k + 1)-th of any, so that a slow stretch of a shared
/// machine (another process on the cores for a second) falls on all of them alike instead of
/// on whichever rung was being timed, and the ratios between rungs keep their meaning. The
/// first sample is one run; after it a set whose run is shorter than [`MIN_SAMPLE_S`] times
/// as many back-to-back runs as make that (a sample is their mean). Returns per set the median
/// wall and thread CPU time (s) of one run, the steps and the Newton iterations.
pub fn time_runs_interleaved(
    text: &str,
    sets: &[Vec<String>],
    repeats: usize,
) -> Result<Vec<(f64, f64, u64, u64)>, String> {
    let scenes = sets
        .iter()
        .map(|s| load(text, s))
        .collect::<Result<Vec<_>, _>>()?;
    let n = scenes.len();
    let (mut walls, mut cpus) = (vec![Vec::new(); n], vec![Vec::new(); n]);
    let mut counts = vec![(0, 0); n];
    let mut batch = vec![1usize; n];
    for round in 0..repeats.max(1) {
        for (i, sc) in scenes.iter().enumerate() {
            let (t0, c0) = (Instant::now(), thread_cpu_s());
            for _ in 0..batch[i] {
                let stats = Simulation::new(sc)
                    .run(&mut NullObserver)
                    .map_err(|e| e.to_string())?;
                counts[i] = (stats.steps, stats.newton_iterations);
            }
            let k = batch[i] as f64;
            walls[i].push(t0.elapsed().as_secs_f64() / k);
            cpus[i].push((thread_cpu_s() - c0) / k);
            if round == 0 {
                batch[i] = runs_per_sample(walls[i][0]);
            }
        }
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        v[v.len() / 2]
    };
    Ok(walls
        .into_iter()
        .zip(cpus)
        .zip(counts)
        .map(|((w, c), (s, it))| (median(w), median(c), s, it))
        .collect())
}

/// Back-to-back runs in one timed sample of a run that took `wall` seconds: enough to last
/// [`MIN_SAMPLE_S`], at most 100.
pub fn runs_per_sample(wall: f64) -> usize {
    if wall >= MIN_SAMPLE_S || !wall.is_finite() {
        return 1;
    }
    ((MIN_SAMPLE_S / wall.max(1e-6)).ceil() as usize).clamp(1, 100)
}

/// Errors of a run against a reference.
#[derive(Debug, Clone, Default)]
pub struct Errors {
    pub pos_rms_m: f64,
    pub impulse_rel: Option<f64>,
    pub onset_s: Option<f64>,
    pub peak_eq2_rel: Option<f64>,
    pub peak_ic_rel: Option<f64>,
}

/// The reference a run is compared with: a fine run, or closed-form values.
pub struct Reference {
    pub samples: Vec<Vec<Vec<f64>>>,
    pub impulse: Vec<Vec<f64>>,
    pub onset: Option<f64>,
    pub peak_eq2: f64,
    pub peak_ic: f64,
}

impl Reference {
    pub fn from_run(m: &Measured) -> Self {
        Self {
            samples: m.samples.clone(),
            impulse: m
                .summary
                .rods
                .iter()
                .map(|r| r.total_impulse_per_node_ns.clone())
                .collect(),
            onset: m.summary.contact_onset_time_s,
            peak_eq2: m.summary.peak_reaction_force_n,
            peak_ic: m.summary.peak_impulse_consistent_force_n,
        }
    }
}

pub fn errors(m: &Measured, r: &Reference) -> Errors {
    let mut sum = 0.0;
    let mut count = 0usize;
    for (a, b) in m.samples.iter().zip(&r.samples) {
        for (qa, qb) in a.iter().zip(b) {
            for k in (0..qa.len()).step_by(2) {
                sum += (qa[k] - qb[k]).powi(2) + (qa[k + 1] - qb[k + 1]).powi(2);
                count += 1;
            }
        }
    }
    let jmax = r.impulse.iter().flatten().fold(0.0f64, |a, b| a.max(*b));
    let impulse_rel = (jmax > 0.0).then(|| {
        m.summary
            .rods
            .iter()
            .zip(&r.impulse)
            .flat_map(|(a, b)| {
                a.total_impulse_per_node_ns
                    .iter()
                    .zip(b)
                    .map(|(x, y)| (x - y).abs())
            })
            .fold(0.0f64, f64::max)
            / jmax
    });
    let rel = |a: f64, b: f64| (b > 0.0).then(|| (a - b).abs() / b);
    Errors {
        pos_rms_m: if count > 0 {
            (sum / count as f64).sqrt()
        } else {
            f64::NAN
        },
        impulse_rel,
        onset_s: match (m.summary.contact_onset_time_s, r.onset) {
            (Some(a), Some(b)) => Some((a - b).abs()),
            _ => None,
        },
        peak_eq2_rel: rel(m.summary.peak_reaction_force_n, r.peak_eq2),
        peak_ic_rel: rel(m.summary.peak_impulse_consistent_force_n, r.peak_ic),
    }
}

/// One benchmark case: a scenario and its ladders.
pub struct Case {
    pub name: &'static str,
    pub text: &'static str,
    pub sets: Vec<String>,
    pub dts: Vec<f64>,
    pub rtols: Vec<f64>,
    /// Reference step (fixed); `None` when the reference is analytic.
    pub ref_dt: Option<f64>,
}

fn cases(quick: bool) -> Vec<Case> {
    let (dts, rtols, ref_dt) = if quick {
        (vec![1e-4, 3e-5, 1e-5], vec![1e-4, 1e-5, 1e-6], 1e-6)
    } else {
        (
            vec![1e-4, 3e-5, 1e-5, 3e-6, 1e-6],
            vec![1e-3, 1e-4, 1e-5, 3e-6, 1e-6, 1e-7],
            1e-7,
        )
    };
    vec![
        Case {
            name: "seed-grasp-r5",
            text: SEED_R5,
            sets: vec![],
            dts: dts.clone(),
            rtols: rtols.clone(),
            ref_dt: Some(ref_dt),
        },
        Case {
            name: "point-mass-plane",
            text: DROP,
            sets: vec![],
            dts: if quick {
                vec![1e-3, 1e-4]
            } else {
                vec![1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 1e-6]
            },
            rtols: rtols.clone(),
            ref_dt: None,
        },
        Case {
            name: "two-prong-grasp",
            text: TWO_PRONG,
            sets: vec![],
            dts: dts.clone(),
            rtols: rtols.clone(),
            ref_dt: Some(ref_dt),
        },
        Case {
            name: "cantilever-gravity",
            text: CANTILEVER,
            sets: vec!["solve.t_end=0.2".into()],
            dts: if quick {
                vec![1e-3, 1e-4]
            } else {
                vec![1e-3, 3e-4, 1e-4, 3e-5, 1e-5]
            },
            rtols: rtols.clone(),
            ref_dt: Some(if quick { 1e-5 } else { 1e-6 }),
        },
    ]
}

/// The point-mass drop in closed form: free fall from H, then at rest on the plane with a
/// perfectly inelastic impact (impulse m v + m g for the rest of the run).
fn drop_reference(samples: usize, summary_window: f64) -> Reference {
    let (h, g, m, t_end) = (0.05, 9.8f64, 0.01, 0.2);
    let t_hit = (2.0 * h / g).sqrt();
    let v = g * t_hit;
    let s = Sampler::new(t_end, samples);
    let samples = s
        .times
        .iter()
        .map(|&t| vec![vec![0.0, if t < t_hit { h - 0.5 * g * t * t } else { 0.0 }]])
        .collect();
    Reference {
        samples,
        impulse: vec![vec![m * v + m * g * (t_end - t_hit)]],
        onset: Some(t_hit),
        // Eq. 2's peak has no limit (it grows like 1/dt); the window force does.
        peak_eq2: f64::NAN,
        peak_ic: m * v / summary_window + m * g,
    }
}

/// One row of the work-precision table.
#[derive(Debug, Clone)]
pub struct Row {
    pub case: String,
    pub strategy: String,
    pub param_name: String,
    pub param: f64,
    pub steps: u64,
    pub newton_iterations: u64,
    pub wall_s: f64,
    /// Median CPU time of the timed runs (s).
    pub cpu_s: f64,
    pub err: Errors,
    pub peak_eq2_n: f64,
    pub peak_ic_n: f64,
}

fn opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x:e}")).unwrap_or_default()
}

/// The accuracy the issue 13 target compares at: 1 % largest per-node impulse error.
pub const IMPULSE_LIMIT: f64 = 0.01;

/// For one case: the cheapest rung of fixed backward Euler and of BDF2 + adaptive + time of
/// impact that are within the impulse error limit, from the same run of the bench.
#[derive(Debug, Clone)]
pub struct Target {
    pub case: String,
    pub limit: f64,
    pub fixed: Option<Row>,
    pub bdf2: Option<Row>,
    /// A second figure, independent of where the rungs fall: each strategy's steps at exactly
    /// the limit, interpolated log-log between the two rungs of its ladder that bracket it
    /// ([`steps_at_limit`]; the same rule for both strategies). `None` when no two rungs
    /// bracket the limit.
    pub fixed_at_limit: Option<f64>,
    pub bdf2_at_limit: Option<f64>,
    /// The same two figures for TR-BDF2 + adaptive + time of impact (compared with fixed
    /// backward Euler by the same rules as BDF2).
    pub tr_bdf2: Option<Row>,
    pub tr_bdf2_at_limit: Option<f64>,
}

/// The steps at which a ladder's impulse error is exactly `limit`: the ladder's (steps, error)
/// rungs sorted by steps, every pair of neighbours whose errors bracket the limit interpolated
/// on the straight line between them in log(steps)–log(error), and the fewest steps of those
/// crossings (a ladder whose error is not monotone in its steps can cross the limit more than
/// once). `None` when no neighbours bracket it (every rung within the limit, or none).
pub fn steps_at_limit(rungs: &[(u64, f64)], limit: f64) -> Option<f64> {
    let mut r: Vec<(u64, f64)> = rungs
        .iter()
        .copied()
        .filter(|&(n, e)| n > 0 && e > 0.0 && e.is_finite())
        .collect();
    r.sort_by_key(|&(n, _)| n);
    r.windows(2)
        .filter_map(|w| {
            let ((n1, e1), (n2, e2)) = (w[0], w[1]);
            if (e1 - limit) * (e2 - limit) > 0.0 {
                return None;
            }
            if e1 == e2 {
                return Some(n1 as f64);
            }
            let (l1, l2) = ((n1 as f64).ln(), (n2 as f64).ln());
            let f = (limit.ln() - e1.ln()) / (e2.ln() - e1.ln());
            Some((l1 + f * (l2 - l1)).exp())
        })
        .min_by(|a, b| a.total_cmp(b))
}

impl Target {
    /// Fewer steps, less wall time and less CPU time of the BDF2 rung against the fixed rung.
    pub fn ratios(&self) -> Option<(f64, f64, f64)> {
        rung_ratios(self.fixed.as_ref()?, self.bdf2.as_ref()?)
    }

    /// The same for the TR-BDF2 rung.
    pub fn tr_ratios(&self) -> Option<(f64, f64, f64)> {
        rung_ratios(self.fixed.as_ref()?, self.tr_bdf2.as_ref()?)
    }

    pub fn describe(&self) -> String {
        let verdict = |r: Option<(f64, f64, f64)>| match r {
            Some((s, w, c)) => {
                format!("{s:.1}x fewer steps, {w:.1}x less wall time, {c:.1}x less CPU time")
            }
            None => "no comparison".into(),
        };
        let at = |n: Option<f64>| n.map_or("not bracketed".into(), |n| format!("{n:.0} steps"));
        let ratio = |x: Option<f64>| match (self.fixed_at_limit, x) {
            (Some(f), Some(b)) => format!(" => {:.1}x fewer steps", f / b),
            _ => String::new(),
        };
        format!(
            "target {} (impulse error <= {} %): {}; {} => {}; {} => {}; at exactly {} % \
             (log-log between the bracketing rungs, every strategy the same way): fixed {}, \
             bdf2+adaptive+toi {}{}, tr_bdf2+adaptive+toi {}{}",
            self.case,
            self.limit * 100.0,
            describe_rung(&self.fixed),
            describe_rung(&self.bdf2),
            verdict(self.ratios()),
            describe_rung(&self.tr_bdf2),
            verdict(self.tr_ratios()),
            self.limit * 100.0,
            at(self.fixed_at_limit),
            at(self.bdf2_at_limit),
            ratio(self.bdf2_at_limit),
            at(self.tr_bdf2_at_limit),
            ratio(self.tr_bdf2_at_limit),
        )
    }
}

/// Fewer steps, less wall and CPU time of rung `b` against rung `f`.
fn rung_ratios(f: &Row, b: &Row) -> Option<(f64, f64, f64)> {
    Some((
        f.steps as f64 / b.steps.max(1) as f64,
        f.wall_s / b.wall_s.max(1e-12),
        f.cpu_s / b.cpu_s.max(1e-12),
    ))
}

fn describe_rung(r: &Option<Row>) -> String {
    match r {
        Some(r) => format!(
            "{} {}={:e}: {} steps, {:.3} ms wall, {:.3} ms CPU, impulse error {:.3} %",
            r.strategy,
            r.param_name,
            r.param,
            r.steps,
            r.wall_s * 1e3,
            r.cpu_s * 1e3,
            r.err.impulse_rel.unwrap_or(f64::NAN) * 100.0
        ),
        None => "no rung of the ladder is within the limit".into(),
    }
}

/// Per case with an impulse error: the fewest-step rung within `limit` of fixed backward Euler,
/// of BDF2 + adaptive + time of impact and of TR-BDF2 + adaptive + time of impact (each
/// second-order strategy is compared with fixed backward Euler by the same rules).
pub fn targets(rows: &[Row], limit: f64) -> Vec<Target> {
    let mut cases: Vec<&str> = rows.iter().map(|r| r.case.as_str()).collect();
    cases.dedup();
    let best = |case: &str, strategy: Strategy| {
        rows.iter()
            .filter(|r| r.case == case && r.strategy == strategy.name())
            .filter(|r| r.err.impulse_rel.is_some_and(|e| e <= limit))
            .min_by_key(|r| r.steps)
            .cloned()
    };
    let at_limit = |case: &str, strategy: Strategy| {
        let rungs: Vec<(u64, f64)> = rows
            .iter()
            .filter(|r| r.case == case && r.strategy == strategy.name())
            .filter_map(|r| Some((r.steps, r.err.impulse_rel?)))
            .collect();
        steps_at_limit(&rungs, limit)
    };
    cases
        .into_iter()
        .filter(|c| {
            // Cases whose impulse error is round-off (the point mass) compare nothing.
            rows.iter()
                .filter(|r| r.case == *c)
                .any(|r| r.err.impulse_rel.is_some_and(|e| e > 1e-10))
        })
        .map(|c| Target {
            case: c.to_string(),
            limit,
            fixed: best(c, Strategy::Fixed),
            bdf2: best(c, Strategy::Bdf2AdaptiveToi),
            fixed_at_limit: at_limit(c, Strategy::Fixed),
            bdf2_at_limit: at_limit(c, Strategy::Bdf2AdaptiveToi),
            tr_bdf2: best(c, Strategy::TrBdf2AdaptiveToi),
            tr_bdf2_at_limit: at_limit(c, Strategy::TrBdf2AdaptiveToi),
        })
        .collect()
}

/// Work-precision: every case under every strategy and rung. Writes `work-precision.csv` and
/// `work-precision.{png,svg}` to `opt.out`. Returns the rows.
pub fn work_precision(opt_: &BenchOptions, log: &mut dyn FnMut(&str)) -> Result<Vec<Row>, String> {
    let samples = 200;
    let mut rows = Vec::new();
    for case in cases(opt_.quick) {
        let reference = match case.ref_dt {
            Some(dt) => {
                log(&format!("{}: reference run, fixed dt = {dt:e}", case.name));
                let mut sets = case.sets.clone();
                sets.extend(Strategy::Fixed.sets(dt));
                Reference::from_run(&measure(case.text, &sets, samples)?)
            }
            None => drop_reference(samples, 1e-3),
        };
        let mut rungs = Vec::new();
        for strategy in STRATEGIES {
            let ladder = match strategy {
                Strategy::Fixed | Strategy::Proximity | Strategy::Bdf2Fixed => &case.dts,
                _ => &case.rtols,
            };
            for &p in ladder {
                let mut sets = case.sets.clone();
                sets.extend(strategy.sets(p));
                rungs.push((strategy, p, sets));
            }
        }
        let all_sets: Vec<Vec<String>> = rungs.iter().map(|r| r.2.clone()).collect();
        let timed = time_runs_interleaved(case.text, &all_sets, opt_.repeats)?;
        for ((strategy, p, sets), (wall, cpu, steps, iters)) in rungs.into_iter().zip(timed) {
            let m = measure(case.text, &sets, samples)?;
            let err = errors(&m, &reference);
            log(&format!(
                "{:<20} {:<13} {}={p:<8e} steps {:>8} wall {:>9.3} ms  pos rms {:.2e} m  impulse {}",
                case.name,
                strategy.name(),
                strategy.param_name(),
                steps,
                wall * 1e3,
                err.pos_rms_m,
                err.impulse_rel.map(|x| format!("{:.2e}", x)).unwrap_or_else(|| "-".into())
            ));
            rows.push(Row {
                case: case.name.into(),
                strategy: strategy.name().into(),
                param_name: strategy.param_name().into(),
                param: p,
                steps,
                newton_iterations: iters,
                wall_s: wall,
                cpu_s: cpu,
                peak_eq2_n: m.summary.peak_reaction_force_n,
                peak_ic_n: m.summary.peak_impulse_consistent_force_n,
                err,
            });
        }
    }
    std::fs::create_dir_all(&opt_.out).map_err(|e| format!("{}: {e}", opt_.out.display()))?;
    let mut csv = String::from(
        "case,strategy,parameter,value,steps,newton_iterations,wall_s,pos_rms_m,impulse_rel_err,onset_err_s,peak_eq2_n,peak_eq2_rel_err,peak_ic_n,peak_ic_rel_err,cpu_s\n",
    );
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{},{},{:e},{},{},{:e},{:e},{},{},{:e},{},{:e},{},{:e}",
            r.case,
            r.strategy,
            r.param_name,
            r.param,
            r.steps,
            r.newton_iterations,
            r.wall_s,
            r.err.pos_rms_m,
            opt(r.err.impulse_rel),
            opt(r.err.onset_s),
            r.peak_eq2_n,
            opt(r.err.peak_eq2_rel),
            r.peak_ic_n,
            opt(r.err.peak_ic_rel),
            r.cpu_s
        );
    }
    crate::record::write_atomic(&opt_.out.join("work-precision.csv"), csv.as_bytes())
        .map_err(|e| e.to_string())?;
    let mut text = String::new();
    for t in targets(&rows, IMPULSE_LIMIT) {
        let line = t.describe();
        log(&line);
        let _ = writeln!(text, "{line}");
    }
    crate::record::write_atomic(
        &opt_.out.join("work-precision-targets.txt"),
        text.as_bytes(),
    )
    .map_err(|e| e.to_string())?;
    let mut panels = Vec::new();
    let case_names: Vec<String> = {
        let mut v: Vec<String> = rows.iter().map(|r| r.case.clone()).collect();
        v.dedup();
        v
    };
    for (metric, label) in [
        ("impulse", "max node impulse error (relative)"),
        ("pos", "position RMS error (m)"),
    ] {
        for c in &case_names {
            let mut series = Vec::new();
            for s in STRATEGIES.map(Strategy::name) {
                let pts: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| &r.case == c && r.strategy == s)
                    .filter_map(|r| {
                        let x = if metric == "impulse" {
                            r.err.impulse_rel?
                        } else {
                            r.err.pos_rms_m
                        };
                        Some((x, r.wall_s))
                    })
                    .collect();
                if !pts.is_empty() {
                    series.push(plot::Series {
                        name: s.into(),
                        points: pts,
                    });
                }
            }
            // A case whose impulse error is at round-off (the point mass: the modified mass
            // method conserves its impulse exactly) has nothing to plot against.
            let noise = series
                .iter()
                .flat_map(|s| s.points.iter())
                .all(|p| p.0 < 1e-10);
            if series.is_empty() || (metric == "impulse" && noise) {
                continue;
            }
            panels.push(plot::Panel {
                title: c.clone(),
                x_label: label.into(),
                y_label: "wall time (s)".into(),
                log_x: true,
                log_y: true,
                series,
            });
        }
    }
    plot::panels(
        &opt_.out.join("work-precision"),
        "gripsim work-precision: wall time against error",
        &panels,
        4,
    )?;
    Ok(rows)
}

/// Cost per step against nodes per prong on the seed grasp geometry (fixed dt = 1e-5, no sink).
pub fn scaling(
    opt_: &BenchOptions,
    log: &mut dyn FnMut(&str),
) -> Result<Vec<(usize, f64, f64)>, String> {
    let nodes: Vec<usize> = if opt_.quick {
        vec![10, 100, 1000]
    } else {
        (0..11).map(|k| 10usize << k).collect()
    };
    let mut out = Vec::new();
    for &n in &nodes {
        let steps = 400usize;
        let sets = vec![
            format!("rod.0.nodes={n}"),
            format!("rod.0.node_mass={:e}", 0.1 / n as f64),
            format!("solve.t_end={:e}", steps as f64 * 1e-5),
        ];
        let (wall, st, iters) = time_run(SEED_R5, &sets, opt_.repeats)?;
        let per_step = wall / st as f64;
        let iters_per_step = iters as f64 / st as f64;
        log(&format!("scaling: {n:>6} nodes: {:.3} µs per step, {iters_per_step:.2} Newton iterations per step", per_step * 1e6));
        out.push((n, per_step, iters_per_step));
    }
    // Ratios are per doubling of the nodes (the ladder doubles; --quick steps by 10x).
    let mut csv = String::from("nodes,seconds_per_step,newton_iterations_per_step,seconds_per_iteration,ratio_per_doubling,iteration_cost_ratio_per_doubling\n");
    for (i, (n, s, it)) in out.iter().enumerate() {
        let (ratio, iratio) = if i > 0 {
            let (n0, s0, it0) = out[i - 1];
            let doublings = (*n as f64 / n0 as f64).log2();
            (
                format!("{:.3}", (s / s0).powf(1.0 / doublings)),
                format!("{:.3}", ((s / it) / (s0 / it0)).powf(1.0 / doublings)),
            )
        } else {
            (String::new(), String::new())
        };
        let _ = writeln!(
            csv,
            "{n},{s:e},{it:.3},{:e},{ratio},{iratio}",
            s / it.max(1e-300)
        );
    }
    std::fs::create_dir_all(&opt_.out).map_err(|e| format!("{}: {e}", opt_.out.display()))?;
    crate::record::write_atomic(&opt_.out.join("scaling.csv"), csv.as_bytes())
        .map_err(|e| e.to_string())?;
    plot::panels(
        &opt_.out.join("scaling"),
        "gripsim: cost per step against nodes per prong",
        &[plot::Panel {
            title: "seed grasp, fixed dt = 1e-5 s, no sink".into(),
            x_label: "nodes per prong".into(),
            y_label: "wall time per step (s)".into(),
            log_x: true,
            log_y: true,
            series: vec![
                plot::Series {
                    name: "per step".into(),
                    points: out.iter().map(|(n, s, _)| (*n as f64, *s)).collect(),
                },
                plot::Series {
                    name: "per Newton iteration".into(),
                    points: out
                        .iter()
                        .map(|(n, s, it)| (*n as f64, s / it.max(1e-300)))
                        .collect(),
                },
            ],
        }],
        1,
    )?;
    Ok(out)
}

/// Outcome of one stress-map cell.
#[derive(Debug, Clone, PartialEq)]
pub enum CellStatus {
    Ok,
    Recovered(u64),
    Refused(String),
}

/// Watches every step for non-finite values and penetration of free nodes.
struct Watch {
    clamped: Vec<Vec<bool>>,
    non_finite: bool,
    max_pen: f64,
    contact: bool,
}

impl Observer for Watch {
    fn on_event(&mut self, e: &Event<'_>) {
        if let Event::StepEnd { rods, .. } = e {
            for (r, v) in rods.iter().enumerate() {
                let all =
                    v.q.iter()
                        .chain(v.u)
                        .chain(v.reaction)
                        .chain(v.impulse)
                        .chain(v.bending_stress);
                if all.clone().any(|x| !x.is_finite()) {
                    self.non_finite = true;
                }
                for (i, g) in v.gap.iter().enumerate() {
                    if !self.clamped[r][i] && g.is_finite() {
                        self.max_pen = self.max_pen.max(-g);
                    }
                    if v.in_contact[i] {
                        self.contact = true;
                    }
                }
            }
        }
    }
}

#[derive(Debug, Clone)]
pub struct Cell {
    pub e: f64,
    pub accel: f64,
    pub nodes: usize,
    pub dt: f64,
    pub status: CellStatus,
    pub steps: u64,
    pub max_penetration: f64,
    pub non_finite: bool,
    pub contact: bool,
}

/// The seed grasp with the fruit moved 1 mm closer and a drive that stops after 5 mm of
/// travel (so the clamp never reaches the fruit), at most 2000 steps of `dt` or 0.03 s.
pub fn stress_cell(e: f64, accel: f64, nodes: usize, dt: f64) -> Cell {
    let t_end = (2000.0 * dt).min(0.03);
    let sets = vec![
        format!("rod.0.E={e:e}"),
        format!("rod.0.nodes={nodes}"),
        format!("rod.0.node_mass={:e}", 0.1 / nodes as f64),
        format!("rod.0.drive={{ kind = \"constant_acceleration\", acceleration = [{:e}, 0.0], stop_travel = 0.005 }}", -accel),
        format!("solve.dt={dt:e}"),
        format!("solve.t_end={t_end:e}"),
        "obstacle.0.center=[-0.049, -0.05]".into(),
    ];
    let mut cell = Cell {
        e,
        accel,
        nodes,
        dt,
        status: CellStatus::Ok,
        steps: 0,
        max_penetration: 0.0,
        non_finite: false,
        contact: false,
    };
    let sc = match load(SEED_R5, &sets) {
        Ok(s) => s,
        Err(msg) => {
            cell.status = CellStatus::Refused(msg);
            return cell;
        }
    };
    let mut sim = Simulation::new(&sc);
    let mut w = Watch {
        clamped: sim.rods.iter().map(|r| r.clamped.clone()).collect(),
        non_finite: false,
        max_pen: 0.0,
        contact: false,
    };
    let res = sim.run(&mut w);
    cell.steps = sim.stats.steps;
    cell.max_penetration = w.max_pen;
    cell.non_finite = w.non_finite;
    cell.contact = w.contact;
    cell.status = match res {
        Err(err) => CellStatus::Refused(err.to_string()),
        Ok(st) if st.backoffs > 0 => CellStatus::Recovered(st.backoffs),
        Ok(_) => CellStatus::Ok,
    };
    cell
}

/// The stress map over E, drive acceleration, nodes per prong and dt. Writes `stress.csv` and
/// `stress.{png,svg}`.
pub fn stress(opt_: &BenchOptions, log: &mut dyn FnMut(&str)) -> Result<Vec<Cell>, String> {
    let (es, accs, nodes, dts): (Vec<f64>, Vec<f64>, Vec<usize>, Vec<f64>) = if opt_.quick {
        (
            vec![1e4, 1e11],
            vec![1.0, 100.0],
            vec![3, 100],
            vec![1e-6, 1e-3],
        )
    } else {
        (
            vec![1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11],
            vec![0.1, 1.0, 10.0, 100.0],
            vec![3, 10, 100, 1000],
            vec![1e-7, 1e-6, 1e-5, 1e-4, 1e-3],
        )
    };
    let mut cells = Vec::new();
    for &n in &nodes {
        for &e in &es {
            for &a in &accs {
                for &dt in &dts {
                    let c = stress_cell(e, a, n, dt);
                    log(&format!(
                        "stress: E={e:.0e} a={a:<5} nodes={n:<5} dt={dt:.0e}: {:?}, {} steps, penetration {:.1e} m{}",
                        c.status,
                        c.steps,
                        c.max_penetration,
                        if c.non_finite { ", NON-FINITE" } else { "" }
                    ));
                    cells.push(c);
                }
            }
        }
    }
    let mut csv = String::from("E_pa,accel_m_s2,nodes,dt_s,status,backoffs,steps,contact,max_penetration_m,non_finite,message\n");
    for c in &cells {
        let (st, b, msg) = match &c.status {
            CellStatus::Ok => ("ok", 0, String::new()),
            CellStatus::Recovered(b) => ("recovered", *b, String::new()),
            CellStatus::Refused(m) => ("refused", 0, m.replace(['"', '\n'], "'")),
        };
        let _ = writeln!(
            csv,
            "{:e},{},{},{:e},{st},{b},{},{},{:e},{},\"{msg}\"",
            c.e, c.accel, c.nodes, c.dt, c.steps, c.contact, c.max_penetration, c.non_finite
        );
    }
    std::fs::create_dir_all(&opt_.out).map_err(|e| format!("{}: {e}", opt_.out.display()))?;
    crate::record::write_atomic(&opt_.out.join("stress.csv"), csv.as_bytes())
        .map_err(|e| e.to_string())?;
    // One map per node count: rows E, columns dt, colour = worst outcome over accelerations.
    let rank = |c: &Cell| -> usize {
        if c.non_finite {
            4
        } else {
            match c.status {
                CellStatus::Ok if c.max_penetration > 1e-9 => 3,
                CellStatus::Ok => 0,
                CellStatus::Recovered(_) => 1,
                CellStatus::Refused(_) => 2,
            }
        }
    };
    let maps = nodes
        .iter()
        .map(|&n| plot::HeatMap {
            title: format!("{n} nodes per prong"),
            row_labels: es.iter().map(|e| format!("E={e:.0e}")).collect(),
            col_labels: dts.iter().map(|d| format!("{d:.0e}")).collect(),
            cells: es
                .iter()
                .map(|&e| {
                    dts.iter()
                        .map(|&dt| {
                            cells
                                .iter()
                                .filter(|c| c.nodes == n && c.e == e && c.dt == dt)
                                .map(rank)
                                .max()
                                .unwrap_or(0)
                        })
                        .collect()
                })
                .collect(),
            legend: vec![
                ("ok".into(), plotters::style::RGBColor(120, 190, 120)),
                (
                    "recovered (dt back-off)".into(),
                    plotters::style::RGBColor(240, 200, 90),
                ),
                (
                    "refused with an error".into(),
                    plotters::style::RGBColor(150, 150, 200),
                ),
                (
                    "penetration > 1e-9 m".into(),
                    plotters::style::RGBColor(230, 120, 60),
                ),
                ("non-finite".into(), plotters::style::RGBColor(200, 30, 30)),
            ],
        })
        .collect::<Vec<_>>();
    plot::heat_maps(
        &opt_.out.join("stress"),
        "gripsim stress map: worst outcome over drive accelerations (columns: dt in s)",
        &maps,
        2,
    )?;
    Ok(cells)
}

/// Default output folder.
pub fn default_out() -> PathBuf {
    Path::new("out").join("bench")
}
