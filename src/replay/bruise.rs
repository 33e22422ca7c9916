//! The bruise rule of `replay check` (and `run --check`, `sweep`): a contact on a compliant
//! fruit whose Hertz peak pressure p₀ exceeds the fruit's bruise threshold (issue 11; the
//! contact law and the thresholds' sources are in docs/model.md). One episode per node and
//! contiguous stretch of steps above the threshold, with the largest pressure, when, and the
//! widest part of the contact above the threshold. A free fruit's own contact with a fixed
//! obstacle (a fruit dropped on the table: no rod, `node` is the body) is a place of its own,
//! named "<fruit> on <obstacle>". A rigid fruit has no pressure and is never flagged.

use serde::Serialize;

/// One contact of one step, as the rule reads it (a live contact view or a recorded one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressureSample {
    /// The rod, or `usize::MAX` for a free body's own contact (then `node` is the body).
    pub rod: usize,
    pub node: usize,
    /// The obstacle pressed: the fruit for a prong's contact, the table for the fruit's own.
    pub obstacle: usize,
    /// Hertz peak pressure p₀ (Pa); 0 at a rigid obstacle.
    pub peak_pressure: f64,
    /// The fruit's bruise threshold (Pa); 0 when it has none.
    pub bruise_pressure: f64,
    /// Half-width of the part of the contact above the threshold (m).
    pub bruise_half_width: f64,
}

impl PressureSample {
    /// A live contact view's pressure, when it has one (a compliant contact).
    pub fn of_view(c: &crate::events::ContactView) -> Option<PressureSample> {
        (c.peak_pressure > 0.0).then_some(PressureSample {
            rod: c.rod,
            node: c.node,
            obstacle: c.obstacle,
            peak_pressure: c.peak_pressure,
            bruise_pressure: c.bruise_pressure,
            bruise_half_width: c.bruise_half_width,
        })
    }

    fn over(&self) -> bool {
        self.bruise_pressure > 0.0 && self.peak_pressure > self.bruise_pressure
    }
}

/// The names a flag's place is given by: the rods', the obstacles' and the free bodies'
/// (in scenario order).
#[derive(Debug, Clone, Copy, Default)]
pub struct Places<'a> {
    pub rods: &'a [String],
    pub obstacles: &'a [String],
    pub bodies: &'a [String],
}

impl Places<'_> {
    /// A rod's name, or for a free body's own contact "<body> on <obstacle>".
    pub fn name(&self, s: &PressureSample) -> String {
        if s.rod == usize::MAX {
            let body = self.bodies.get(s.node).map_or("fruit", String::as_str);
            let on = self
                .obstacles
                .get(s.obstacle)
                .map_or("an obstacle", String::as_str);
            format!("{body} on {on}")
        } else {
            self.rods.get(s.rod).cloned().unwrap_or_default()
        }
    }
}

fn index_or_null<S: serde::Serializer>(i: &usize, s: S) -> Result<S::Ok, S::Error> {
    if *i == usize::MAX {
        s.serialize_none()
    } else {
        s.serialize_u64(*i as u64)
    }
}

/// One stretch of a node's contact above the bruise threshold.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BruiseFlag {
    /// The rod (null for a free fruit's own contact with a fixed obstacle: then `node` is the
    /// body and `rod_name` says "<fruit> on <obstacle>").
    #[serde(serialize_with = "index_or_null")]
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    /// The obstacle pressed: the fruit for a prong's contact, the fixed obstacle for the
    /// fruit's own.
    pub obstacle: usize,
    /// First and last step above the threshold, and their times (s).
    pub step: u64,
    pub t: f64,
    pub last_step: u64,
    pub last_t: f64,
    /// The largest p₀ of the stretch (Pa) and when (s).
    pub max_pressure_pa: f64,
    pub max_pressure_t: f64,
    pub bruise_pressure_pa: f64,
    /// max p₀ / threshold.
    pub ratio: f64,
    /// Widest part of the contact above the threshold (m, the full width).
    pub max_bruise_width_m: f64,
}

impl BruiseFlag {
    /// Where, for a report: `rod left node 7`, or `apple on table` for a fruit's own contact.
    pub fn place(&self) -> String {
        if self.rod == usize::MAX {
            self.rod_name.clone()
        } else {
            format!("rod {} node {}", self.rod_name, self.node)
        }
    }
}

/// The rule's state: the open stretches, and the closed ones.
#[derive(Debug, Clone, Default)]
pub struct BruiseRule {
    open: Vec<BruiseFlag>,
    pub flags: Vec<BruiseFlag>,
}

impl BruiseRule {
    /// The compliant contacts of one accepted step.
    pub fn step(&mut self, step: u64, t: f64, samples: &[PressureSample], names: &Places<'_>) {
        for s in samples.iter().filter(|s| s.over()) {
            let at = self
                .open
                .iter()
                .position(|f| (f.rod, f.node, f.obstacle) == (s.rod, s.node, s.obstacle));
            let f = match at {
                Some(k) => &mut self.open[k],
                None => {
                    self.open.push(BruiseFlag {
                        rod: s.rod,
                        rod_name: names.name(s),
                        node: s.node,
                        obstacle: s.obstacle,
                        step,
                        t,
                        last_step: step,
                        last_t: t,
                        max_pressure_pa: 0.0,
                        max_pressure_t: t,
                        bruise_pressure_pa: s.bruise_pressure,
                        ratio: 0.0,
                        max_bruise_width_m: 0.0,
                    });
                    self.open.last_mut().expect("just pushed")
                }
            };
            f.last_step = step;
            f.last_t = t;
            f.max_bruise_width_m = f.max_bruise_width_m.max(2.0 * s.bruise_half_width);
            if s.peak_pressure > f.max_pressure_pa {
                f.max_pressure_pa = s.peak_pressure;
                f.max_pressure_t = t;
                f.bruise_pressure_pa = s.bruise_pressure;
                f.ratio = s.peak_pressure / s.bruise_pressure;
            }
        }
        // Stretches that did not go on in this step are over.
        let mut k = 0;
        while k < self.open.len() {
            if self.open[k].last_step != step {
                self.flags.push(self.open.remove(k));
            } else {
                k += 1;
            }
        }
    }

    /// Everything found, open stretches closed at the last step, in time order.
    pub fn finish(mut self) -> Vec<BruiseFlag> {
        self.flags.append(&mut self.open);
        self.flags.sort_by(|a, b| {
            a.t.total_cmp(&b.t)
                .then((a.rod, a.node).cmp(&(b.rod, b.node)))
        });
        self.flags
    }
}

/// The bruise rule on a live run's one event stream (either dimension): the compliant
/// contacts of every accepted step, named by the run's rods and obstacles.
#[derive(Debug, Default)]
pub struct BruiseObserver {
    rule: BruiseRule,
    rods: Vec<String>,
    obstacles: Vec<String>,
    /// The scenario expects the fruit to bruise (`[expect] bruised`): a bruise is then not
    /// flagged, its absence is.
    expected: bool,
    samples: Vec<PressureSample>,
}

impl BruiseObserver {
    pub fn new(expected: bool) -> BruiseObserver {
        BruiseObserver {
            expected,
            ..BruiseObserver::default()
        }
    }

    /// The scenario expects its fruit to bruise (`[expect] bruised = true`).
    pub fn expected(&self) -> bool {
        self.expected
    }

    /// The flags `replay check` counts as `bruise`: every stretch above the threshold, or,
    /// where the scenario expects a bruise, 1 when there was none.
    pub fn count(&self) -> usize {
        let found = self.rule.flags.len() + self.rule.open.len();
        if self.expected {
            usize::from(found == 0)
        } else {
            found
        }
    }

    /// Everything found, in time order.
    pub fn finish(self) -> Vec<BruiseFlag> {
        self.rule.finish()
    }
}

impl crate::events::Observer for BruiseObserver {
    fn on_event(&mut self, event: &crate::events::Event<'_>) {
        use crate::events::Event;
        match event {
            Event::RunStart(info) => {
                self.rods = info.rods.iter().map(|r| r.name.clone()).collect();
                self.obstacles = info.obstacle_names.to_vec();
            }
            Event::StepEnd {
                step, t, contacts, ..
            } => {
                self.samples.clear();
                self.samples
                    .extend(contacts.iter().filter_map(PressureSample::of_view));
                let places = Places {
                    rods: &self.rods,
                    obstacles: &self.obstacles,
                    bodies: &[],
                };
                self.rule.step(*step, *t, &self.samples, &places);
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(node: usize, p: f64) -> PressureSample {
        PressureSample {
            rod: 0,
            node,
            obstacle: 1,
            peak_pressure: p,
            bruise_pressure: 1e5,
            bruise_half_width: if p > 1e5 { 1e-4 } else { 0.0 },
        }
    }

    #[test]
    fn a_stretch_above_the_threshold_is_one_flag_with_its_peak() {
        let rods = vec!["prong".to_string()];
        let names = Places {
            rods: &rods,
            ..Places::default()
        };
        let mut r = BruiseRule::default();
        r.step(1, 0.1, &[s(3, 0.9e5)], &names);
        r.step(2, 0.2, &[s(3, 1.2e5), s(4, 1.1e5)], &names);
        r.step(3, 0.3, &[s(3, 1.5e5)], &names);
        r.step(4, 0.4, &[s(3, 0.8e5)], &names);
        r.step(5, 0.5, &[s(3, 1.3e5)], &names);
        let f = r.finish();
        let got: Vec<_> = f
            .iter()
            .map(|f| (f.node, f.step, f.last_step, f.max_pressure_pa))
            .collect();
        assert_eq!(
            got,
            vec![(3, 2, 3, 1.5e5), (4, 2, 2, 1.1e5), (3, 5, 5, 1.3e5)]
        );
        assert_eq!(f[0].max_pressure_t, 0.3);
        assert!((f[0].ratio - 1.5).abs() < 1e-15);
        assert_eq!(f[0].max_bruise_width_m, 2e-4);
        assert_eq!(f[0].rod_name, "prong");
    }

    #[test]
    fn a_rigid_fruit_or_one_without_a_threshold_is_never_flagged() {
        let mut r = BruiseRule::default();
        let rigid = PressureSample {
            bruise_pressure: 0.0,
            ..s(1, 1e9)
        };
        r.step(1, 0.1, &[rigid, s(2, 0.0)], &Places::default());
        assert!(r.finish().is_empty());
    }

    #[test]
    fn a_fruits_own_contact_is_named_by_the_fruit_and_the_obstacle() {
        let (rods, obstacles, bodies) = (
            vec!["prong".to_string()],
            vec!["table".to_string(), "apple".to_string()],
            vec!["apple".to_string()],
        );
        let names = Places {
            rods: &rods,
            obstacles: &obstacles,
            bodies: &bodies,
        };
        let table = PressureSample {
            rod: usize::MAX,
            obstacle: 0,
            ..s(0, 1.2e5)
        };
        let mut r = BruiseRule::default();
        // The prong's node 0 and the fruit (body 0) on the table are two places.
        r.step(1, 0.1, &[table, s(0, 1.1e5)], &names);
        let f = r.finish();
        assert_eq!(f.len(), 2);
        assert_eq!(f[0].rod_name, "prong");
        assert_eq!(f[1].rod_name, "apple on table");
        assert_eq!((f[1].node, f[1].obstacle), (0, 0));
        let j = serde_json::to_value(&f[1]).unwrap();
        assert_eq!(j["rod"], serde_json::Value::Null);
        assert_eq!(j["rod_name"], "apple on table");
    }
}
