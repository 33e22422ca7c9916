//! What a Python run keeps in memory from the one event stream: the time of every recorded
//! state, each rod's positions and velocities, the contacts and free bodies of every step
//! (long tables, one row per contact or body per step) and the run's events. Only what was
//! asked for is kept.

use super::{f64_bytes, i64_bytes};
use gripsim::events::{Event, Observer};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// A long table: named columns of f64 or i64 (−1 for none).
#[derive(Default)]
struct Table {
    floats: Vec<(&'static str, Vec<f64>)>,
    ints: Vec<(&'static str, Vec<i64>)>,
}

impl Table {
    fn float(&mut self, i: usize, name: &'static str, v: f64) {
        if self.floats.len() <= i {
            self.floats.push((name, Vec::new()));
        }
        self.floats[i].1.push(v);
    }
    fn int(&mut self, i: usize, name: &'static str, v: i64) {
        if self.ints.len() <= i {
            self.ints.push((name, Vec::new()));
        }
        self.ints[i].1.push(v);
    }
    fn to_python<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let cols = PyList::empty(py);
        for (name, v) in &self.ints {
            cols.append((*name, "i8", i64_bytes(py, v)?))?;
        }
        for (name, v) in &self.floats {
            cols.append((*name, "f8", f64_bytes(py, v)?))?;
        }
        Ok(cols)
    }
}

/// An index as a table's integer: −1 for none (`usize::MAX`).
fn idx(i: usize) -> i64 {
    if i == usize::MAX {
        -1
    } else {
        i as i64
    }
}

pub struct Keep {
    positions: bool,
    velocities: bool,
    contacts: bool,
    bodies: bool,
    events: bool,
    dim: u8,
    rods: Vec<(String, usize)>,
    steps: Vec<i64>,
    t: Vec<f64>,
    q: Vec<Vec<f64>>,
    u: Vec<Vec<f64>>,
    contact_rows: Table,
    body_rows: Table,
    body_names: Vec<String>,
    /// (kind, step, t, text).
    event_rows: Vec<(&'static str, u64, f64, String)>,
    /// `check=True`: the replay check's detector on the live run (planar).
    pub check: Option<gripsim::replay::detect::DetectObserver>,
}

impl Keep {
    /// Keeps what `what` names: `positions`, `velocities`, `contacts`, `bodies`, `events`.
    pub fn new(what: &[String]) -> Keep {
        let has = |k: &str| what.iter().any(|w| w == k);
        Keep {
            positions: has("positions"),
            velocities: has("velocities"),
            contacts: has("contacts"),
            bodies: has("bodies"),
            events: has("events"),
            dim: 2,
            rods: Vec::new(),
            steps: Vec::new(),
            t: Vec::new(),
            q: Vec::new(),
            u: Vec::new(),
            contact_rows: Table::default(),
            body_rows: Table::default(),
            body_names: Vec::new(),
            event_rows: Vec::new(),
            check: None,
        }
    }

    fn step_end(
        &mut self,
        step: u64,
        t: f64,
        rods: &[gripsim::events::RodStepView],
        contacts: &[gripsim::events::ContactView],
        bodies: &[gripsim::events::BodyView],
    ) {
        self.steps.push(step as i64);
        self.t.push(t);
        for (i, r) in rods.iter().enumerate() {
            if self.positions {
                self.q[i].extend_from_slice(r.q);
            }
            if self.velocities {
                self.u[i].extend_from_slice(r.u);
            }
        }
        if self.contacts {
            for c in contacts {
                self.contact(step, t, c);
            }
        }
        if self.bodies {
            for (i, b) in bodies.iter().enumerate() {
                self.body(step, t, i, b);
            }
        }
    }

    fn contact(&mut self, step: u64, t: f64, c: &gripsim::events::ContactView) {
        let r = &mut self.contact_rows;
        for (i, (name, v)) in [
            ("step", step as i64),
            ("rod", idx(c.rod)),
            ("node", c.node as i64),
            ("segment", idx(c.segment)),
            ("obstacle", idx(c.obstacle)),
            ("body", idx(c.body)),
            ("stuck", i64::from(c.stuck)),
        ]
        .into_iter()
        .enumerate()
        {
            r.int(i, name, v);
        }
        let n = c.normal;
        let p = c.point;
        for (i, (name, v)) in [
            ("t", t),
            ("weight", c.weight),
            ("x", p[0]),
            ("y", p[1]),
            ("z", p[2]),
            ("nx", n[0]),
            ("ny", n[1]),
            ("nz", n[2]),
            ("normal_force", c.normal_force),
            ("friction_force", c.friction_force),
            ("slip_velocity", c.slip_velocity),
            ("utilisation", c.utilisation),
            ("mu_s", c.mu_s),
            ("indentation", c.indentation),
            ("half_width", c.half_width),
            ("peak_pressure", c.peak_pressure),
        ]
        .into_iter()
        .enumerate()
        {
            r.float(i, name, v);
        }
    }

    fn body(&mut self, step: u64, t: f64, i: usize, b: &gripsim::events::BodyView) {
        if self.body_names.len() <= i {
            self.body_names.push(b.name.to_string());
        }
        let r = &mut self.body_rows;
        r.int(0, "step", step as i64);
        r.int(1, "body", i as i64);
        r.int(2, "obstacle", b.obstacle as i64);
        let (p, v, f) = (b.position, b.velocity, b.contact_force);
        for (k, (name, x)) in [
            ("t", t),
            ("x", p[0]),
            ("y", p[1]),
            ("z", p[2]),
            ("angle", b.angle),
            ("vx", v[0]),
            ("vy", v[1]),
            ("vz", v[2]),
            ("fx", f[0]),
            ("fy", f[1]),
            ("fz", f[2]),
        ]
        .into_iter()
        .enumerate()
        {
            r.float(k, name, x);
        }
    }

    fn event(&mut self, event: &Event<'_>) {
        let row = match *event {
            Event::ConstraintAdded(c) => (
                "contact_added",
                c.step,
                c.t,
                format!("rod {} node {} on obstacle.{}", c.rod, c.node, c.obstacle),
            ),
            Event::ConstraintReleased(c, why) => (
                "contact_released",
                c.step,
                c.t,
                format!(
                    "rod {} node {} from obstacle.{} ({why:?})",
                    c.rod, c.node, c.obstacle
                ),
            ),
            Event::DtChanged {
                step,
                t,
                old,
                new,
                reason,
            } => ("dt", step, t, format!("dt {old:e} -> {new:e} s ({reason})")),
            Event::NewtonFailed {
                step, t, reason, ..
            } => ("newton_failed", step, t, reason.to_string()),
            Event::Warning { step, t, message } => ("warning", step, t, message.to_string()),
            Event::FrictionChanged(_) => self.described("friction", event),
            Event::BodyContactChanged { .. } => self.described("body_contact", event),
            Event::PhaseChanged { .. } => self.described("phase", event),
            _ => return,
        };
        self.event_rows.push(row);
    }

    fn described(&self, kind: &'static str, event: &Event<'_>) -> (&'static str, u64, f64, String) {
        let (step, t, text) = event.describe().unwrap_or_default();
        (kind, step, t, text)
    }

    /// Sets `dimension`, `rods` (name, nodes), `steps`, `t` and what was kept in `d`.
    pub fn to_python(&self, py: Python<'_>, d: &Bound<'_, PyDict>) -> PyResult<()> {
        d.set_item("dimension", self.dim)?;
        d.set_item("rods", self.rods.clone())?;
        d.set_item("steps", i64_bytes(py, &self.steps)?)?;
        d.set_item("t", f64_bytes(py, &self.t)?)?;
        if self.positions {
            let q: PyResult<Vec<_>> = self.q.iter().map(|q| f64_bytes(py, q)).collect();
            d.set_item("positions", q?)?;
        }
        if self.velocities {
            let u: PyResult<Vec<_>> = self.u.iter().map(|u| f64_bytes(py, u)).collect();
            d.set_item("velocities", u?)?;
        }
        if self.contacts {
            d.set_item("contacts", self.contact_rows.to_python(py)?)?;
        }
        if self.bodies {
            d.set_item("bodies", self.body_rows.to_python(py)?)?;
            d.set_item("body_names", self.body_names.clone())?;
        }
        if self.events {
            d.set_item("events", self.event_rows.clone())?;
        }
        Ok(())
    }
}

impl Observer for Keep {
    fn wants_steps(&self) -> bool {
        true
    }
    fn on_event(&mut self, event: &Event<'_>) {
        if let Some(c) = self.check.as_mut() {
            c.on_event(event);
        }
        match *event {
            Event::RunStart(info) => {
                self.dim = info.dimension;
                self.rods = info
                    .rods
                    .iter()
                    .map(|r| (r.name.clone(), r.nodes))
                    .collect();
                self.q = vec![Vec::new(); self.rods.len()];
                self.u = vec![Vec::new(); self.rods.len()];
            }
            Event::StepEnd {
                step,
                t,
                rods,
                contacts,
                bodies,
                ..
            } => self.step_end(step, t, rods, contacts, bodies),
            _ if self.events => self.event(event),
            _ => {}
        }
    }
}
