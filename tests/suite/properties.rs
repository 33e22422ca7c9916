//! Property tests: random valid small scenarios.
//!
//! Each case is one or two rods of 3–30 nodes (straight or parabolic, optionally clamped and
//! driven with a constant acceleration), given a downward velocity, just above one or two
//! obstacles (circles, planes, ellipses, and ramps beside the rods that make corners with the
//! others) placed so that every node starts outside them, with E
//! in 1e4..1e11 Pa, density 100..10 000 kg/m³ and dt in 1e-6..1e-3 s, run for a few hundred
//! steps at most (milliseconds a case). The scenario goes through the real TOML reader.
//!
//! Properties, for every case:
//! 1. every step's q, u, reaction, impulse and bending stress (and the gap) are finite;
//! 2. no free (non-clamped) node is more than 1e-9 m inside an obstacle after any step;
//! 3. two runs of the same scenario give bit-identical final states and counters.
//!
//! A run may instead stop with a clean `SimError::Diverged` (the solver refused a step it could
//! not solve even after halving dt): that is allowed, and 1–3 must still hold for every step
//! it accepted. A panic is never allowed.
//!
//! 64 cases (`PROPTEST_CASES` overrides); the file runs in a few seconds in release. The
//! test prints how many cases made contact and how many stopped on a `SimError`.

use gripsim::events::{Event, NullObserver, Observer};
use gripsim::solver::SimError;
use gripsim::{Scenario, Simulation};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};

/// The smallest height of any node above y = 0 is `lift`; every obstacle lies below y = 0
/// (planes tilted at most so that they stay below the rods), so the rods start outside them.
#[derive(Debug, Clone)]
struct RodCase {
    nodes: usize,
    /// true: parabola x = x0 + a (L − s)², y = y0 − s; false: straight.
    parabola: bool,
    x0: f64,
    length: f64,
    /// Straight: angle of the rod from +x (0 … π: it rises from node 0). Parabola: a (1/m).
    shape_param: f64,
    youngs_modulus: f64,
    density: f64,
    /// Rect b × h, or a circle of radius h/2.
    rect: bool,
    b: f64,
    h: f64,
    /// 0: none, 1: node 0, 2: nodes 0 and 1.
    clamped: usize,
    acceleration: [f64; 2],
    velocity: [f64; 2],
}

#[derive(Debug, Clone)]
enum ObstacleCase {
    Circle {
        cx: f64,
        r: f64,
    },
    /// Tilt as a fraction of the largest tilt that keeps the plane below the rods.
    Plane {
        tilt: f64,
    },
    Ellipse {
        cx: f64,
        a: f64,
        b: f64,
        angle: f64,
    },
    /// A plane rising at `angle` (rad) to the right of the rods, `gap` (m) beyond their
    /// rightmost node: with the floor-like obstacles it makes corners.
    Ramp {
        gap: f64,
        angle: f64,
    },
}

#[derive(Debug, Clone)]
struct Case {
    rods: Vec<RodCase>,
    obstacles: Vec<ObstacleCase>,
    /// Height of the lowest node above y = 0 (m).
    lift: f64,
    /// Depth of the obstacles' tops below y = 0 (m).
    sink: f64,
    dt: f64,
    steps: u32,
    gravity: f64,
    /// 0 fixed, 1 proximity, 2 adaptive.
    stepping: u32,
    time_of_impact: bool,
}

/// Log-uniform in [lo, hi].
fn log_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (0.0..=1.0f64).prop_map(move |u| lo * (hi / lo).powf(u))
}

fn rod_case() -> impl Strategy<Value = RodCase> {
    (
        (3usize..=30, any::<bool>(), -0.05..0.05f64, 0.02..0.1f64),
        (0.0..1.0f64, log_uniform(1e4, 1e11), log_uniform(100.0, 1e4)),
        (any::<bool>(), 0.005..0.02f64, 0.0005..0.01f64, 0usize..3),
        (
            prop_oneof![Just([0.0, 0.0]), [-20.0..20.0f64, -20.0..20.0f64]],
            (-0.5..0.5f64, -3.0..0.5f64),
        ),
    )
        .prop_map(
            |(
                (nodes, parabola, x0, length),
                (u, youngs_modulus, density),
                (rect, b, h, clamped),
                (acceleration, (vx, vy)),
            )| RodCase {
                nodes,
                parabola,
                x0,
                length,
                // Straight: 0 … π. Parabola: |a| ≤ 15 1/m (the rest shape turns < 90°).
                shape_param: if parabola {
                    30.0 * u - 15.0
                } else {
                    std::f64::consts::PI * u
                },
                youngs_modulus,
                density,
                rect,
                b,
                h,
                clamped,
                acceleration,
                velocity: [vx, vy],
            },
        )
}

fn obstacle_case() -> impl Strategy<Value = ObstacleCase> {
    prop_oneof![
        (-0.1..0.1f64, 0.005..0.1f64).prop_map(|(cx, r)| ObstacleCase::Circle { cx, r }),
        (-1.0..1.0f64).prop_map(|tilt| ObstacleCase::Plane { tilt }),
        (-0.1..0.1f64, 0.005..0.08f64, 0.005..0.08f64, -3.2..3.2f64)
            .prop_map(|(cx, a, b, angle)| ObstacleCase::Ellipse { cx, a, b, angle }),
        (1e-5..0.005f64, 0.1..1.5f64).prop_map(|(gap, angle)| ObstacleCase::Ramp { gap, angle }),
    ]
}

fn case() -> impl Strategy<Value = Case> {
    (
        prop::collection::vec(rod_case(), 1..=2),
        prop::collection::vec(obstacle_case(), 1..=2),
        (log_uniform(1e-5, 5e-3), 0.0..1.0f64),
        (log_uniform(1e-6, 1e-3), 5u32..=300, 0.0..20.0f64),
        (0u32..3, any::<bool>()),
    )
        .prop_map(
            |(rods, obstacles, (lift, sink), (dt, steps, gravity), (stepping, toi))| Case {
                rods,
                obstacles,
                lift,
                sink: sink * lift,
                dt,
                steps,
                gravity,
                stepping,
                time_of_impact: toi,
            },
        )
}

/// Largest |x| any node of any case can have (m), for the plane tilt bound.
const X_MAX: f64 = 0.2;

impl Case {
    /// The largest x of any node (straight: an end; parabola: the root or the tip).
    fn x_right(&self) -> f64 {
        self.rods
            .iter()
            .map(|r| {
                let far = if r.parabola {
                    r.x0 + r.shape_param * r.length * r.length
                } else {
                    r.x0 + r.length * r.shape_param.cos()
                };
                far.max(r.x0)
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    fn toml(&self) -> String {
        let t_end = self.dt * self.steps as f64;
        let mut s = format!(
            "name = \"prop\"\n[solve]\nt_end = {t_end:e}\ndt = {:e}\ngravity = [0.0, {:e}]\n\
             time_of_impact = {}\n",
            self.dt, -self.gravity, self.time_of_impact
        );
        match self.stepping {
            1 => {
                s += &format!(
                    "stepping = \"proximity\"\ndt_near = {:e}\nnear_distance = {:e}\n",
                    self.dt / 10.0,
                    2.0 * self.lift
                )
            }
            2 => {
                s += &format!(
                    "stepping = \"adaptive\"\ndt_min = {:e}\ndt_max = {:e}\n",
                    self.dt / 20.0,
                    self.dt * 4.0
                )
            }
            _ => {}
        }
        for (k, r) in self.rods.iter().enumerate() {
            s += &format!("[[rod]]\nname = \"rod{k}\"\nnodes = {}\n", r.nodes);
            if r.parabola {
                // Lowest point (the tip) at y0 − L = lift.
                s += &format!(
                    "shape = {{ kind = \"parabola\", x0 = {:e}, y0 = {:e}, a = {:e}, length = {:e} }}\n",
                    r.x0,
                    self.lift + r.length,
                    r.shape_param,
                    r.length
                );
            } else {
                let end = [
                    r.x0 + r.length * r.shape_param.cos(),
                    self.lift + r.length * r.shape_param.sin(),
                ];
                s += &format!(
                    "shape = {{ kind = \"straight\", start = [{:e}, {:e}], end = [{:e}, {:e}] }}\n",
                    r.x0, self.lift, end[0], end[1]
                );
            }
            s += &format!("E = {:e}\ndensity = {:e}\n", r.youngs_modulus, r.density);
            if r.rect {
                s += &format!(
                    "section = {{ kind = \"rect\", b = {:e}, h = {:e} }}\n",
                    r.b, r.h
                );
            } else {
                s += &format!(
                    "section = {{ kind = \"circle\", radius = {:e} }}\n",
                    r.h / 2.0
                );
            }
            if r.clamped > 0 {
                let list: Vec<String> = (0..r.clamped).map(|i| i.to_string()).collect();
                s += &format!("clamped = [{}]\n", list.join(", "));
                if r.acceleration != [0.0, 0.0] {
                    s += &format!(
                        "drive = {{ kind = \"constant_acceleration\", acceleration = [{:e}, {:e}] }}\n",
                        r.acceleration[0], r.acceleration[1]
                    );
                }
            }
            s += &format!("velocity = [{:e}, {:e}]\n", r.velocity[0], r.velocity[1]);
        }
        for o in &self.obstacles {
            s += "[[obstacle]]\n";
            match *o {
                ObstacleCase::Circle { cx, r } => {
                    s += &format!(
                        "kind = \"circle\"\ncenter = [{cx:e}, {:e}]\nradius = {r:e}\n",
                        -r - self.sink
                    )
                }
                ObstacleCase::Plane { tilt } => {
                    // Through (0, −sink), rising at most (lift + sink)/2 over X_MAX.
                    let slope = tilt * 0.5 * (self.lift + self.sink) / X_MAX;
                    let theta = slope.atan();
                    s += &format!(
                        "kind = \"plane\"\npoint = [0.0, {:e}]\nnormal = [{:e}, {:e}]\n",
                        -self.sink,
                        -theta.sin(),
                        theta.cos()
                    )
                }
                ObstacleCase::Ramp { gap, angle } => {
                    // Through (x_r, −sink): solid where y + sink < tan(angle) (x − x_r).
                    s += &format!(
                        "kind = \"plane\"\npoint = [{:e}, {:e}]\nnormal = [{:e}, {:e}]\n",
                        self.x_right() + gap,
                        -self.sink,
                        -angle.sin(),
                        angle.cos()
                    )
                }
                ObstacleCase::Ellipse { cx, a, b, angle } => {
                    s += &format!(
                        "kind = \"ellipse\"\ncenter = [{cx:e}, {:e}]\na = {a:e}\nb = {b:e}\nangle = {angle:e}\n",
                        -a.max(b) - self.sink
                    )
                }
            }
        }
        s
    }
}

/// Checks every step as it ends; keeps the first violation.
#[derive(Default)]
struct Checker {
    clamped: Vec<Vec<bool>>,
    steps: u64,
    /// Whether any node was in contact at the end of any step.
    contact: bool,
    violation: Option<String>,
}

impl Observer for Checker {
    fn on_event(&mut self, e: &Event<'_>) {
        match e {
            Event::RunStart(info) => {
                self.clamped = info.rods.iter().map(|r| r.clamped.clone()).collect();
            }
            Event::StepEnd { step, t, rods, .. } => {
                self.steps += 1;
                if self.violation.is_some() {
                    return;
                }
                for (r, v) in rods.iter().enumerate() {
                    self.contact |= v.in_contact.iter().any(|&c| c);
                    let arrays: [(&str, &[f64]); 5] = [
                        ("q", v.q),
                        ("u", v.u),
                        ("reaction", v.reaction),
                        ("impulse", v.impulse),
                        ("bending_stress", v.bending_stress),
                    ];
                    for (name, xs) in arrays {
                        if let Some(k) = xs.iter().position(|x| !x.is_finite()) {
                            self.violation = Some(format!(
                                "step {step} (t = {t}): rod {r} {name}[{k}] = {}",
                                xs[k]
                            ));
                            return;
                        }
                    }
                    for (i, &g) in v.gap.iter().enumerate() {
                        if g.is_nan() {
                            self.violation =
                                Some(format!("step {step}: rod {r} node {i} gap is NaN"));
                            return;
                        }
                        if self.clamped[r][i] {
                            continue;
                        }
                        if g < -1e-9 {
                            self.violation = Some(format!(
                                "step {step} (t = {t}): free node {i} of rod {r} is {:.3e} m inside an obstacle",
                                -g
                            ));
                            return;
                        }
                    }
                }
            }
            _ => {}
        }
    }
}

/// Final state and counters, bit for bit.
fn fingerprint(sim: &Simulation) -> Vec<u64> {
    let mut v = vec![sim.step, sim.t.to_bits(), sim.stats.newton_iterations];
    v.extend([sim.stats.contact_passes, sim.stats.backoffs]);
    for r in 0..sim.rods.len() {
        v.extend(sim.positions(r).iter().map(|x| x.to_bits()));
        v.extend(sim.velocities(r).iter().map(|x| x.to_bits()));
    }
    v
}

/// Case count: `PROPTEST_CASES`, else 64.
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64)
}

#[test]
fn random_valid_scenarios_stay_finite_outside_and_deterministic() {
    use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
    let (done, contact, diverged, steps) = (
        AtomicU64::new(0),
        AtomicU64::new(0),
        AtomicU64::new(0),
        AtomicU64::new(0),
    );
    let mut runner = TestRunner::new(Config {
        cases: cases(),
        failure_persistence: None,
        ..Config::default()
    });
    let result = runner.run(&case(), |c| {
        let text = c.toml();
        // The generator's obstacles and starts are built for the seed's contact model.
        let seed = [
            "contact.surface=centreline".into(),
            "contact.points=nodes".into(),
        ];
        let sc = Scenario::from_str(&text, "prop.toml", &seed)
            .unwrap_or_else(|e| panic!("the generator made an invalid scenario: {e}\n{text}"));

        let mut checker = Checker::default();
        let mut sim = Simulation::new(&sc);
        let result = sim.run(&mut checker);
        if let Some(v) = &checker.violation {
            return Err(TestCaseError::fail(format!(
                "{v}\nresult: {result:?}\n{text}"
            )));
        }
        match &result {
            // StepEnd comes once for the initial state, then once per accepted step.
            Ok(stats) => prop_assert_eq!(stats.steps + 1, checker.steps),
            // Allowed: a clean stop that names where the solver gave up.
            Err(SimError::Diverged { .. }) => {}
            Err(e) => return Err(TestCaseError::fail(format!("unexpected error {e}\n{text}"))),
        }

        // The same scenario again, observed by nobody: bit for bit the same.
        let mut again = Simulation::new(&sc);
        let result2 = again.run(&mut NullObserver);
        prop_assert_eq!(result.is_ok(), result2.is_ok(), "{}", text);
        prop_assert_eq!(fingerprint(&sim), fingerprint(&again), "{}", text);

        done.fetch_add(1, Relaxed);
        steps.fetch_add(sim.stats.steps, Relaxed);
        contact.fetch_add(u64::from(checker.contact), Relaxed);
        diverged.fetch_add(u64::from(result.is_err()), Relaxed);
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    eprintln!(
        "{} cases, {} steps: {} with contact, {} stopped on a clean SimError::Diverged",
        done.load(Relaxed),
        steps.load(Relaxed),
        contact.load(Relaxed),
        diverged.load(Relaxed)
    );
}
