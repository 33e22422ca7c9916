//! The Rerun view of a run, read back by the Rerun SDK (tests/py/read_rrd.py, in the test
//! venv that tests/py/setup_venv.py makes): what a reviewer relies on when looking at a
//! contact oscillation — phase and pass on every iterate, arrows proportional to the force at
//! the printed scale, distinct series colours, and bookmarks at the right steps.

use crate::common::{gripsim, message_json, run_ok, scenario, venv, ROOT};
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::Command;

/// The report of tests/py/read_rrd.py.
fn read_rrd(path: &Path) -> Value {
    let out = Command::new(venv().join("bin/python"))
        .arg(Path::new(ROOT).join("tests/py/read_rrd.py"))
        .arg(path)
        .env("RERUN_ANALYTICS", "false")
        .output()
        .expect("the venv's python runs");
    assert!(
        out.status.success(),
        "read_rrd.py {} failed:\n{}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("read_rrd.py prints JSON")
}

/// Every /sim/step and /sim/contact message of an MCAP, in order.
fn mcap_messages(path: &Path) -> Vec<(String, Value)> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.channel.topic.clone(), message_json(&m))
        })
        .collect()
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// "1 cm = 100 N" → metres per newton.
fn printed_scale(legend: &str) -> f64 {
    let part = legend;
    let (len, force) = part.split_once('=').expect("'L = F N'");
    let len = len.trim();
    let (v, unit) = len.split_once(' ').expect("a length with a unit");
    let m: f64 = v.parse::<f64>().unwrap()
        * match unit {
            "m" => 1.0,
            "cm" => 1e-2,
            "mm" => 1e-3,
            "µm" => 1e-6,
            u => panic!("unit {u}"),
        };
    let f: f64 = force.trim().trim_end_matches(" N").parse().unwrap();
    m / f
}

#[test]
fn the_seed_grasp_view_shows_phases_honest_arrows_and_bookmarks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (rrd, mcap, summary) = (d.join("r5.rrd"), d.join("r5.mcap"), d.join("r5.json"));
    run_ok(
        gripsim()
            .arg("run")
            .arg(scenario("seed-grasp-r5"))
            .args(["-q", "--detail", "iteration", "--rrd"])
            .arg(&rrd)
            .arg("--mcap")
            .arg(&mcap)
            .arg("--summary")
            .arg(&summary),
    );
    let summary: Value = serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
    let rep = read_rrd(&rrd);
    let msgs = mcap_messages(&mcap);

    // Every iterate carries its phase and pass, in the order the MCAP has them.
    let iterates = rep["iterates"]["/scene/prong/iterate"].as_array().unwrap();
    let drawn: Vec<&Value> = iterates
        .iter()
        .filter(|r| r["strips"].as_u64().unwrap_or(0) > 0)
        .collect();
    let mcap_iterations: Vec<(String, u64)> = msgs
        .iter()
        .filter(|(t, _)| t == "/sim/iteration")
        .map(|(_, m)| {
            (
                m["phase"].as_str().unwrap().to_string(),
                m["pass"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        drawn.len() as u64,
        summary["newton_iterations"].as_u64().unwrap()
    );
    assert_eq!(drawn.len(), mcap_iterations.len());
    let mut correctors = 0;
    for (row, (phase, pass)) in drawn.iter().zip(&mcap_iterations) {
        assert_eq!(row["phase"].as_str(), Some(phase.as_str()), "{row}");
        assert_eq!(row["pass"].as_u64(), Some(*pass), "{row}");
        assert!(row["newton_iteration"].as_u64().unwrap() >= 1, "{row}");
        assert_eq!(phase == "predictor", *pass == 0, "{row}");
        correctors += (phase == "corrector") as usize;
    }
    assert!(correctors >= 5, "the seed grasp has corrector passes");

    // Arrows: length / |R| is the same for every arrow and equals the printed scale.
    let legend = rep["legend"][0].as_str().expect("a printed scale");
    let scale = printed_scale(legend);
    let mut reactions: BTreeMap<u64, Vec<f64>> = BTreeMap::new();
    for (t, m) in &msgs {
        if t == "/sim/step" {
            let rod = &m["rods"][0];
            let norm = f64s(&rod["reaction_norm"]);
            let contact: Vec<bool> = rod["in_contact"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| c.as_bool().unwrap())
                .collect();
            let f = (0..norm.len()).filter(|&i| contact[i]).map(|i| norm[i]);
            reactions.insert(m["step"].as_u64().unwrap(), f.collect());
        }
    }
    let mut checked = 0;
    let mut longest = (0.0f64, 0.0f64);
    for row in rep["reactions"]["/scene/prong/reactions"]
        .as_array()
        .unwrap()
    {
        let step = row["step"].as_u64().unwrap();
        let forces = &reactions[&step];
        let vectors = row["vectors"].as_array().unwrap();
        assert_eq!(vectors.len(), forces.len(), "step {step}");
        for (v, &f) in vectors.iter().zip(forces) {
            let v = f64s(v);
            let len = v[0].hypot(v[1]);
            if f > 1e-3 {
                let ratio = len / f;
                assert!(
                    (ratio / scale - 1.0).abs() < 1e-4,
                    "step {step}: arrow {len} m for {f} N, printed scale {scale} m/N ({legend})"
                );
                checked += 1;
                if f > longest.1 {
                    longest = (len, f);
                }
            }
        }
    }
    assert!(checked > 1000, "{checked} arrows checked");
    let peak = summary["peak_reaction_force_n"].as_f64().unwrap();
    // The MCAP's reaction norms are f32 (format 4): the summary's peak to f32 resolution.
    assert!((longest.1 - peak).abs() <= f64::from(f32::EPSILON) * peak);
    // The 194 N peak is not squashed: 50 times the arrow of a 3.9 N contact.
    assert!((longest.0 / (3.9 * scale) - peak / 3.9).abs() < 1e-3 * peak);

    // Bookmarks: first contact, every contact change, the peak, at the right steps.
    let marks = rep["bookmarks"].as_array().unwrap();
    let text = |m: &Value| m["text"].as_str().unwrap().to_string();
    let find = |what: &str| {
        marks
            .iter()
            .find(|m| text(m).contains(what))
            .unwrap_or_else(|| panic!("a bookmark with {what:?} in {marks:?}"))
    };
    let ns = |t: f64| (t * 1e9).round() as i64;
    let pk = find("peak eq. 2 reaction");
    assert_eq!(pk["level"], "BOOKMARK");
    let peak_t = summary["peak_reaction_time_s"].as_f64().unwrap();
    assert_eq!(pk["sim_time_ns"].as_i64().unwrap(), ns(peak_t), "{pk}");
    assert!(text(pk).contains(&format!("{peak:.4} N")), "{pk}");
    let node = summary["peak_reaction_node"]["node"].as_u64().unwrap();
    assert!(text(pk).contains(&format!("node {node} ")), "{pk}");
    let peak_step = reactions
        .iter()
        // The MCAP's reaction norms are f32: the step whose norm is the peak rounded to f32.
        .find(|(_, f)| f.contains(&(peak as f32 as f64)))
        .map(|(s, _)| *s)
        .unwrap();
    assert_eq!(pk["step"].as_u64(), Some(peak_step));
    assert!(text(pk).contains(&format!("step {peak_step},")), "{pk}");
    let first = find("first contact");
    let onset = summary["contact_onset_time_s"].as_f64().unwrap();
    assert_eq!(first["sim_time_ns"].as_i64().unwrap(), ns(onset), "{first}");
    let changes: Vec<u64> = msgs
        .iter()
        .filter(|(t, _)| t == "/sim/contact")
        .map(|(_, m)| m["step"].as_u64().unwrap())
        .collect();
    let marked: Vec<u64> = marks
        .iter()
        .filter(|m| {
            let t = text(m);
            t.contains("contact added") || t.contains("contact released")
        })
        .map(|m| m["step"].as_u64().unwrap())
        .collect();
    assert_eq!(
        marked, changes,
        "one bookmark per contact change, at its step"
    );
    assert!(marks.iter().all(|m| m["iteration"].as_i64().is_some()));
    find("peak impulse-consistent force");
}

#[test]
fn two_prong_series_have_distinct_colours() {
    let dir = tempfile::tempdir().unwrap();
    let rrd = dir.path().join("two.rrd");
    run_ok(
        gripsim()
            .arg("run")
            .arg(scenario("two-prong-grasp"))
            .args([
                "-q",
                "--set",
                "solve.t_end=0.001",
                "--detail",
                "iteration",
                "--rrd",
            ])
            .arg(&rrd),
    );
    let rep = read_rrd(&rrd);
    let series = rep["series"].as_object().unwrap();
    // Group the series as the views show them: per kind and rod (one entity, a line per
    // node), and the per-rod solver series.
    let mut groups: BTreeMap<String, Vec<(String, u64)>> = BTreeMap::new();
    for (ent, s) in series {
        let parts: Vec<&str> = ent.trim_start_matches('/').split('/').collect();
        let group = match parts.as_slice() {
            ["plots", kind, rod] => format!("{kind}/{rod}"),
            ["solver", _, leaf] => format!("solver/{leaf}"),
            ["solver", _] => "solver/per_step".to_string(),
            _ => continue,
        };
        let colors = s["colors"].as_array().expect("colours");
        let names = s["names"].as_array().expect("names");
        assert_eq!(colors.len(), names.len(), "{ent}: a name per colour");
        for (k, (c, n)) in colors.iter().zip(names).enumerate() {
            assert!(
                !n.as_str().unwrap_or("").is_empty(),
                "{ent} line {k} has a name"
            );
            groups
                .entry(group.clone())
                .or_default()
                .push((format!("{ent}[{k}]"), c.as_u64().expect("a colour")));
        }
    }
    for kind in ["reaction", "force_ic", "impulse", "bending_stress"] {
        for rod in ["left", "right"] {
            let g = &groups[&format!("{kind}/{rod}")];
            assert_eq!(g.len(), 10, "{kind}/{rod}: one line per node");
        }
    }
    assert_eq!(
        groups["solver/log10_residual"].len(),
        2,
        "one series per rod"
    );
    for (group, members) in &groups {
        let colours: BTreeSet<u64> = members.iter().map(|m| m.1).collect();
        assert_eq!(
            colours.len(),
            members.len(),
            "{group}: every series has its own colour: {members:?}"
        );
    }
    // Stable: node i has the same colour on both rods.
    assert_eq!(
        groups["reaction/left"]
            .iter()
            .map(|m| m.1)
            .collect::<Vec<_>>(),
        groups["reaction/right"]
            .iter()
            .map(|m| m.1)
            .collect::<Vec<_>>()
    );
}

/// A compliant fruit's contacts in the `.rrd` (issue 11): the pressure as a colour along each
/// pressed contact (`scene/pressure`, 16 pieces a contact, purple where it bruises) and the most
/// pressed contact's indentation drawn to scale in the zoom (`zoom/contact/indentation`, mm),
/// step for step the figures of the MCAP's contacts; the peak pressure is bookmarked.
#[test]
fn a_compliant_grasp_shows_pressure_along_the_contact_and_the_indentation_to_scale() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (rrd, mcap, summary) = (d.join("a.rrd"), d.join("a.mcap"), d.join("a.json"));
    run_ok(
        gripsim()
            .arg("run")
            .arg(scenario("seed-grasp-e1gpa"))
            .args([
                "-q",
                "--detail",
                "step",
                "--set",
                "contact.surface=face",
                "--set",
                "obstacle.0.center=[-0.055,-0.05]",
                "--set",
                "obstacle.0.material=apple",
                "--set",
                "solve.dt=2e-4",
                "--rrd",
            ])
            .arg(&rrd)
            .arg("--mcap")
            .arg(&mcap)
            .arg("--summary")
            .arg(&summary),
    );
    let rep = read_rrd(&rrd);
    let summary: Value = serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
    // Per step: the pressed contacts of the MCAP, and the most pressed one's indentation.
    let mut pressed: BTreeMap<u64, (usize, f64, bool)> = BTreeMap::new();
    for (t, m) in mcap_messages(&mcap) {
        if t != "/sim/step" {
            continue;
        }
        let cs: Vec<&Value> = m["contacts"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|c| c["half_width"].as_f64().unwrap_or(0.0) > 0.0)
            .collect();
        if let Some(top) = cs.iter().max_by(|a, b| {
            let p = |c: &Value| c["peak_pressure"].as_f64().unwrap();
            p(a).total_cmp(&p(b))
        }) {
            let bruises = cs.iter().any(|c| {
                c["peak_pressure"].as_f64().unwrap() > c["bruise_pressure"].as_f64().unwrap()
            });
            pressed.insert(
                m["step"].as_u64().unwrap(),
                (cs.len(), top["indentation"].as_f64().unwrap(), bruises),
            );
        }
    }
    assert!(pressed.len() > 50, "{} pressed steps", pressed.len());
    let zoom = rep["zoom"].as_array().unwrap();
    let colours = rep["pressure"].as_array().unwrap();
    assert_eq!(zoom.len(), pressed.len());
    assert_eq!(colours.len(), pressed.len());
    const PURPLE: u64 = (150 << 24) | (60 << 16) | (200 << 8) | 255;
    let mut purple_steps = 0;
    for (z, p) in zoom.iter().zip(colours) {
        let step = z["step"].as_u64().unwrap();
        let (n, depth, bruises) = pressed[&step];
        let v = f64s(&z["vectors"][0]);
        assert!(
            v[0] == 0.0 && (v[1] + 1e3 * depth).abs() <= 1e-6 * (1e3 * depth),
            "{z} {depth}"
        );
        assert_eq!(p["step"].as_u64(), Some(step));
        assert_eq!(p["strips"].as_u64(), Some(16 * n as u64), "{p}");
        let purple = p["colors"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c.as_u64() == Some(PURPLE));
        assert_eq!(purple, bruises, "step {step}");
        purple_steps += purple as usize;
    }
    assert!(purple_steps > 0, "the 1 GPa prong bruises the apple");
    // The bookmark names the run's peak pressure, as the summary does.
    let peak = summary["contact_pressure"]["max_pressure_pa"]
        .as_f64()
        .unwrap();
    let mark = rep["bookmarks"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|b| b["text"].as_str())
        .find(|t| t.contains("peak contact pressure"))
        .expect("a peak pressure bookmark");
    assert!(
        mark.contains(&format!("{:.1} kPa", peak / 1e3))
            || mark.contains(&format!("{:.3} MPa", peak / 1e6)),
        "{mark} vs {peak}"
    );
}
