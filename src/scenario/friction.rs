//! `[friction]`: Coulomb coefficients, one default and any number of named pairs.
//!
//! ```toml
//! [friction]
//! mu_s = 0.6          # static coefficient of every contact pair (default 0: frictionless)
//! mu_k = 0.5          # kinetic coefficient (default mu_s; at most mu_s)
//! [[friction.pair]]
//! between = ["fruit", "table"]   # a rod or particle name and/or an obstacle name
//! mu_s = 0.4
//! mu_k = 0.3
//! ```

use super::reader::TableReader;
use super::ScenarioError;
use crate::contact::friction::{Coulomb, FrictionTable};
use toml::Value;

const FRICTION_KEYS: &[&str] = &["mu_s", "mu_k", "pair"];
const PAIR_KEYS: &[&str] = &["between", "mu_s", "mu_k"];

/// Read `[friction]` (absent: frictionless everywhere). `names` are every rod, particle and
/// obstacle name a pair may refer to.
pub fn parse(top: &TableReader, names: &[&str]) -> Result<FrictionTable, ScenarioError> {
    let Some(f) = top.opt_table("friction", FRICTION_KEYS)? else {
        return Ok(FrictionTable::default());
    };
    let default = coulomb(&f, Coulomb::FRICTIONLESS)?;
    let mut pairs = Vec::new();
    match f.get("pair") {
        None => {}
        Some(Value::Array(a)) => {
            for (i, v) in a.iter().enumerate() {
                let p = f.table_value(&format!("pair.{i}"), v, PAIR_KEYS)?;
                let between = p.array("between")?.ok_or_else(|| {
                    p.err_hint(
                        "between",
                        None,
                        "missing required key",
                        "give the two names, e.g. between = [\"left\", \"fruit\"]",
                    )
                })?;
                let mut two = Vec::new();
                for (j, v) in between.iter().enumerate() {
                    let s = p.str_value(&format!("between.{j}"), v)?;
                    if !names.contains(&s) {
                        return Err(p.err_hint(
                            &format!("between.{j}"),
                            Some(v),
                            format!("no rod, particle or obstacle is named {s:?}"),
                            format!("names here: {}", names.join(", ")),
                        ));
                    }
                    two.push(s.to_string());
                }
                if two.len() != 2 {
                    return Err(p.err(
                        "between",
                        p.get("between"),
                        format!("expected two names, found {}", two.len()),
                    ));
                }
                let c = coulomb(&p, default)?;
                p.finish()?;
                pairs.push((two[0].clone(), two[1].clone(), c));
            }
        }
        Some(other) => {
            return Err(f.err(
                "pair",
                Some(other),
                "expected an array of [[friction.pair]] tables",
            ))
        }
    }
    f.finish()?;
    Ok(FrictionTable { default, pairs })
}

/// `mu_s` and `mu_k` of a table: finite, ≥ 0, mu_k ≤ mu_s; mu_k defaults to mu_s, a missing
/// mu_s to `fallback`'s.
fn coulomb(r: &TableReader, fallback: Coulomb) -> Result<Coulomb, ScenarioError> {
    let read = |key: &'static str| -> Result<Option<f64>, ScenarioError> {
        match r.get(key) {
            None => Ok(None),
            Some(v) => {
                let x = r.num_value(key, v)?;
                if x < 0.0 {
                    return Err(r.err_hint(
                        key,
                        Some(v),
                        "a friction coefficient must not be negative",
                        "use 0 for a frictionless pair",
                    ));
                }
                Ok(Some(x))
            }
        }
    };
    let mu_s = read("mu_s")?;
    let mu_k = read("mu_k")?;
    let (mu_s, mu_k) = match (mu_s, mu_k) {
        (Some(s), Some(k)) => (s, k),
        (Some(s), None) => (s, s),
        (None, Some(k)) => (fallback.mu_s.max(k), k),
        (None, None) => (fallback.mu_s, fallback.mu_k),
    };
    if mu_k > mu_s {
        return Err(r.err_hint(
            "mu_k",
            r.get("mu_k"),
            format!("the kinetic coefficient exceeds the static one (mu_s = {mu_s})"),
            "Coulomb friction needs mu_k ≤ mu_s",
        ));
    }
    Ok(Coulomb { mu_s, mu_k })
}
