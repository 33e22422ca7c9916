//! Motion laws: the distance s(τ) (m along a direction, or rad for a rotation) covered τ
//! seconds into a phase, and its rate ṡ(τ).
//!
//! `constant_velocity` and `constant_acceleration` are unbounded (they run until an end
//! condition stops them); `trapezoid`, `s_curve` and `table` are profiles that complete at
//! their own end time, after which s stays at its final value and ṡ = 0.

/// A scalar motion law. Validated by whoever builds it (the scenario reader): speeds,
/// accelerations, distances and durations are finite and > 0.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "law", rename_all = "snake_case")]
pub enum Law {
    /// s = v τ.
    ConstantVelocity { speed: f64 },
    /// From rest: s = ½ a τ².
    ConstantAcceleration { acceleration: f64 },
    /// Accelerate, cruise, decelerate: C¹ position, piecewise-constant acceleration.
    Trapezoid(Trapezoid),
    /// Minimum jerk: s = D (10u³ − 15u⁴ + 6u⁵), u = τ/T; velocity and acceleration are
    /// continuous and zero at both ends.
    SCurve { distance: f64, duration: f64 },
    /// Piecewise linear through (t, s) points; ṡ is the slope of the current segment.
    Table(Table),
}

/// A trapezoidal velocity profile over `distance` D: acceleration A for `t_accel`, cruise at
/// `peak_speed` V, deceleration A for `t_accel` again, done at `duration` T.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Trapezoid {
    pub distance: f64,
    pub peak_speed: f64,
    pub acceleration: f64,
    pub t_accel: f64,
    pub duration: f64,
}

impl Trapezoid {
    /// From a maximum speed and an acceleration. When the distance is too short to reach
    /// `max_speed` (D < V²/A) the profile is a triangle with peak speed √(D A).
    pub fn from_speed(distance: f64, max_speed: f64, acceleration: f64) -> Trapezoid {
        let peak = if max_speed * max_speed / acceleration <= distance {
            max_speed
        } else {
            (distance * acceleration).sqrt()
        };
        let t_accel = peak / acceleration;
        Trapezoid {
            distance,
            peak_speed: peak,
            acceleration,
            t_accel,
            duration: t_accel + distance / peak,
        }
    }

    /// From a duration: one third accelerating, one third cruising, one third decelerating
    /// (V = 1.5 D/T, A = 4.5 D/T²).
    pub fn from_duration(distance: f64, duration: f64) -> Trapezoid {
        let t_accel = duration / 3.0;
        let peak = distance / (duration - t_accel);
        Trapezoid {
            distance,
            peak_speed: peak,
            acceleration: peak / t_accel,
            t_accel,
            duration,
        }
    }

    fn eval(&self, tau: f64) -> (f64, f64) {
        let (a, ta, v) = (self.acceleration, self.t_accel, self.peak_speed);
        if tau <= ta {
            (0.5 * a * tau * tau, a * tau)
        } else if tau <= self.duration - ta {
            (0.5 * a * ta * ta + v * (tau - ta), v)
        } else if tau < self.duration {
            let r = self.duration - tau;
            (self.distance - 0.5 * a * r * r, a * r)
        } else {
            (self.distance, 0.0)
        }
    }

    /// First τ at which s = l (0 < l < D).
    fn time_to(&self, l: f64) -> f64 {
        let (a, ta, v) = (self.acceleration, self.t_accel, self.peak_speed);
        let s_accel = 0.5 * a * ta * ta;
        if l <= s_accel {
            (2.0 * l / a).sqrt()
        } else if l <= self.distance - s_accel {
            ta + (l - s_accel) / v
        } else {
            self.duration - (2.0 * (self.distance - l) / a).sqrt()
        }
    }
}

/// The points of a `table` law: times strictly increasing from 0, values finite, the first 0.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Table {
    t: Vec<f64>,
    s: Vec<f64>,
}

/// Why a list of points is not a valid table: the index of the offending point and what is
/// wrong with it.
#[derive(Debug, Clone, PartialEq)]
pub struct TableIssue {
    pub index: usize,
    pub message: String,
}

impl Table {
    /// Checks: at least two points, all finite, the first point (0, 0), times strictly
    /// increasing.
    pub fn new(points: &[[f64; 2]]) -> Result<Table, TableIssue> {
        let issue = |index: usize, message: String| Err(TableIssue { index, message });
        if points.len() < 2 {
            return issue(
                points.len().saturating_sub(1),
                format!("a table needs at least 2 points, found {}", points.len()),
            );
        }
        for (i, p) in points.iter().enumerate() {
            if !p[0].is_finite() || !p[1].is_finite() {
                return issue(i, "must be finite (nan and inf are not allowed)".into());
            }
            if i == 0 && p[0] != 0.0 {
                return issue(0, format!("the first time must be 0, found t = {}", p[0]));
            }
            if i == 0 && p[1] != 0.0 {
                return issue(
                    0,
                    format!(
                        "the first value must be 0 (a phase starts where the last one ended), found {}",
                        p[1]
                    ),
                );
            }
            if i > 0 && p[0] <= points[i - 1][0] {
                return issue(
                    i,
                    format!(
                        "times must increase strictly: t = {} follows t = {}",
                        p[0],
                        points[i - 1][0]
                    ),
                );
            }
        }
        Ok(Table {
            t: points.iter().map(|p| p[0]).collect(),
            s: points.iter().map(|p| p[1]).collect(),
        })
    }

    /// The points, as (t, s).
    pub fn points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.t.iter().copied().zip(self.s.iter().copied())
    }

    fn duration(&self) -> f64 {
        self.t[self.t.len() - 1]
    }

    fn eval(&self, tau: f64) -> (f64, f64) {
        let last = self.t.len() - 1;
        if tau >= self.t[last] {
            return (self.s[last], 0.0);
        }
        // Segment i: t[i] <= tau < t[i+1].
        let i = self.t.partition_point(|&t| t <= tau).saturating_sub(1);
        let (t0, t1, s0, s1) = (self.t[i], self.t[i + 1], self.s[i], self.s[i + 1]);
        let slope = (s1 - s0) / (t1 - t0);
        (s0 + (s1 - s0) * ((tau - t0) / (t1 - t0)), slope)
    }

    /// First τ at which |s| = l, if the table gets there.
    fn time_to(&self, l: f64) -> Option<f64> {
        for i in 0..self.t.len() - 1 {
            let (s0, s1) = (self.s[i], self.s[i + 1]);
            if s1.abs() >= l {
                let target = l.copysign(s1);
                let f = (target - s0) / (s1 - s0);
                return Some(self.t[i] + f * (self.t[i + 1] - self.t[i]));
            }
        }
        None
    }
}

/// Minimum-jerk shape 10u³ − 15u⁴ + 6u⁵ and its derivative.
fn min_jerk(u: f64) -> (f64, f64) {
    let u2 = u * u;
    let u3 = u2 * u;
    (
        u3 * (10.0 + u * (-15.0 + 6.0 * u)),
        u2 * (30.0 + u * (-60.0 + 30.0 * u)),
    )
}

impl Law {
    /// Position s and rate ṡ at τ ≥ 0 into the phase (τ < 0 is taken as 0). Profiles hold
    /// their final value with ṡ = 0 from their end on.
    pub fn eval(&self, tau: f64) -> (f64, f64) {
        let tau = tau.max(0.0);
        match self {
            Law::ConstantVelocity { speed } => (speed * tau, *speed),
            Law::ConstantAcceleration { acceleration: a } => (0.5 * a * tau * tau, a * tau),
            Law::Trapezoid(tr) => tr.eval(tau),
            Law::SCurve { distance, duration } => {
                if tau >= *duration {
                    return (*distance, 0.0);
                }
                let (f, df) = min_jerk(tau / duration);
                (distance * f, distance * df / duration)
            }
            Law::Table(tb) => tb.eval(tau),
        }
    }

    /// When a profile completes (s reaches its final value and stops); None for the
    /// unbounded laws.
    pub fn profile_end(&self) -> Option<f64> {
        match self {
            Law::ConstantVelocity { .. } | Law::ConstantAcceleration { .. } => None,
            Law::Trapezoid(tr) => Some(tr.duration),
            Law::SCurve { duration, .. } => Some(*duration),
            Law::Table(tb) => Some(tb.duration()),
        }
    }

    /// The first τ at which the travel |s| reaches `l` (> 0), if it does (before or at the
    /// profile's end).
    pub fn time_to_travel(&self, l: f64) -> Option<f64> {
        match self {
            Law::ConstantVelocity { speed } => (*speed > 0.0).then(|| l / speed),
            Law::ConstantAcceleration { acceleration: a } => {
                (*a > 0.0).then(|| (2.0 * l / a).sqrt())
            }
            Law::Trapezoid(tr) => (l < tr.distance).then(|| tr.time_to(l)),
            Law::SCurve { distance, duration } => {
                (l < *distance).then(|| duration * invert_min_jerk(l / distance))
            }
            Law::Table(tb) => tb.time_to(l),
        }
    }

    /// The largest |s̈| of the law (m/s² or rad/s²), the acceleration scale it imposes.
    /// `constant_velocity` and `table` change ṡ in steps (at their start, at a table's
    /// points): no finite acceleration, 0 here.
    pub fn peak_acceleration(&self) -> f64 {
        match self {
            Law::ConstantVelocity { .. } | Law::Table(_) => 0.0,
            Law::ConstantAcceleration { acceleration } => acceleration.abs(),
            Law::Trapezoid(tr) => tr.acceleration,
            // s̈ = D/T² (60u − 180u² + 120u³), largest at u = 1/2 ∓ √3/6: 10√3/3 · D/T².
            Law::SCurve { distance, duration } => {
                10.0 * 3f64.sqrt() / 3.0 * distance.abs() / (duration * duration)
            }
        }
    }

    /// The law's name as the scenario writes it.
    pub fn name(&self) -> &'static str {
        match self {
            Law::ConstantVelocity { .. } => "constant_velocity",
            Law::ConstantAcceleration { .. } => "constant_acceleration",
            Law::Trapezoid(_) => "trapezoid",
            Law::SCurve { .. } => "s_curve",
            Law::Table(_) => "table",
        }
    }
}

/// u ∈ [0, 1] with 10u³ − 15u⁴ + 6u⁵ = f (0 < f < 1), by bisection to the last bit (the shape
/// is strictly increasing on (0, 1)). Deterministic.
fn invert_min_jerk(f: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if min_jerk(mid).0 < f {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}
