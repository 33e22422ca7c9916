//! Design studies: a grid of scenario variants run in parallel, one result folder per case,
//! resumable, shardable across a batch system, with a summary table and plots
//! (`docs/studies.md`).
//!
//! - [`sweep`]: the grid, the runs, resuming, shards and merging, `summary.csv`.
//! - [`plots`]: per-case force, bending stress and shape figures; per-sweep metric figures.
//! - [`window`]: the grasp window — the drop and bruise boundaries along a knob — and its map
//!   over design parameters (each design one case of the sweep machinery); [`window_plot`]
//!   draws the map.
//!
//! A case is the base scenario with the sweep's `--set` assignments and then one value of every
//! `--vary` key applied, in that order, exactly as `gripsim run SCENARIO --set … --set KEY=VALUE`
//! would: the case's `summary.json` is the one `run --summary` writes.

pub mod indent;
pub mod plots;
pub mod sweep;
pub mod window;
pub mod window_plot;

pub use sweep::{
    merge, run_sweep, CasePlots, CaseRecord, Manifest, MergeOptions, MergeReport, Metrics,
    SweepOptions, SweepReport,
};

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Why a sweep could not run or finish.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// A malformed `--vary`, `--shard` or other argument.
    #[error("{0}")]
    Usage(String),
    /// A case's scenario does not load (with the case's assignments in the message).
    #[error("{0}")]
    Scenario(String),
    #[error("{path}: {message}")]
    Io { path: PathBuf, message: String },
    /// The output folder holds results of a different sweep.
    #[error("{0}")]
    Mismatch(String),
    /// A merge found cases that no input folder has finished.
    #[error("{0}")]
    Incomplete(String),
}

pub(crate) fn io_err(path: &std::path::Path, e: impl std::fmt::Display) -> StudyError {
    StudyError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// One `--vary`: a scenario key (dotted path, as `--set`) and its values as `--set` text.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Vary {
    pub key: String,
    pub values: Vec<String>,
}

impl std::str::FromStr for Vary {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        parse_vary(s)
    }
}

/// Parse `KEY=V1,V2,…` (commas inside `[…]`, `{…}` or quotes do not split) or
/// `KEY=START:STOP:COUNT[:log]` (COUNT values, evenly or log-spaced, both ends included).
pub fn parse_vary(spec: &str) -> Result<Vary, String> {
    let hint = "expected KEY=V1,V2,... or KEY=START:STOP:COUNT (e.g. obstacle.0.radius=0.05,0.04 or rod.0.E=1e6:1e9:4:log)";
    let Some((key, rhs)) = spec.split_once('=') else {
        return Err(format!("--vary {spec:?}: {hint}"));
    };
    let key = key.trim();
    let rhs = rhs.trim();
    if key.is_empty() || rhs.is_empty() || key.split('.').any(|p| p.is_empty()) {
        return Err(format!("--vary {spec:?}: {hint}"));
    }
    let values = match parse_range(rhs).map_err(|e| format!("--vary {spec:?}: {e}"))? {
        Some(v) => v,
        None => split_top_level(rhs),
    };
    if values.iter().any(|v| v.is_empty()) {
        return Err(format!(
            "--vary {spec:?}: an empty value (two commas in a row?)"
        ));
    }
    let mut seen = std::collections::HashSet::new();
    for v in &values {
        if !seen.insert(v.as_str()) {
            return Err(format!("--vary {spec:?}: the value {v:?} is listed twice"));
        }
    }
    Ok(Vary {
        key: key.to_string(),
        values,
    })
}

/// Split on commas that are not inside brackets, braces or quotes.
fn split_top_level(s: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut quote: Option<char> = None;
    let mut cur = String::new();
    for c in s.chars() {
        match (quote, c) {
            (Some(q), _) if c == q => quote = None,
            (Some(_), _) => {}
            (None, '"' | '\'') => quote = Some(c),
            (None, '[' | '{') => depth += 1,
            (None, ']' | '}') => depth -= 1,
            (None, ',') if depth == 0 => {
                out.push(cur.trim().to_string());
                cur.clear();
                continue;
            }
            _ => {}
        }
        cur.push(c);
    }
    out.push(cur.trim().to_string());
    out
}

/// `START:STOP:COUNT[:lin|:log]`, or None when the text is not of that form.
fn parse_range(s: &str) -> Result<Option<Vec<String>>, String> {
    let parts: Vec<&str> = s.split(':').map(str::trim).collect();
    if !(parts.len() == 3 || parts.len() == 4) {
        return Ok(None);
    }
    let (Ok(a), Ok(b), Ok(n)) = (
        parts[0].parse::<f64>(),
        parts[1].parse::<f64>(),
        parts[2].parse::<usize>(),
    ) else {
        return Ok(None);
    };
    let log = match parts.get(3) {
        None | Some(&"lin") => false,
        Some(&"log") => true,
        Some(other) => return Err(format!("unknown spacing {other:?}: use lin or log")),
    };
    if !(a.is_finite() && b.is_finite()) {
        return Err("START and STOP must be finite".into());
    }
    if n == 0 {
        return Err("COUNT must be at least 1".into());
    }
    if n > sweep::MAX_CASES {
        // Refused before a value is made (1e8 values took gigabytes).
        return Err(format!(
            "COUNT {n} is more than a sweep takes (at most {} cases)",
            sweep::MAX_CASES
        ));
    }
    if log && !(a > 0.0 && b > 0.0) {
        return Err("log spacing needs START > 0 and STOP > 0".into());
    }
    if n == 1 {
        return Ok(Some(vec![parts[0].to_string()]));
    }
    // Integer ranges stay integers (node counts, iteration limits).
    if !log {
        if let (Ok(ia), Ok(ib)) = (parts[0].parse::<i64>(), parts[1].parse::<i64>()) {
            let steps = (n - 1) as i64;
            if (ib - ia) % steps == 0 {
                let d = (ib - ia) / steps;
                return Ok(Some(
                    (0..n as i64).map(|i| (ia + i * d).to_string()).collect(),
                ));
            }
        }
    }
    let m = (n - 1) as f64;
    let vals = (0..n)
        .map(|i| {
            let f = i as f64 / m;
            let v = if i == 0 {
                a
            } else if i == n - 1 {
                b
            } else if log {
                10f64.powf(a.log10() + (b.log10() - a.log10()) * f)
            } else {
                a + (b - a) * f
            };
            // 12 significant digits: 0.045, not 0.045000000000000005.
            let r: f64 = format!("{v:.11e}").parse().unwrap_or(v);
            format!("{r:?}")
        })
        .collect();
    Ok(Some(vals))
}

/// `--shard I/N`: this process runs the cases whose grid index k has k mod N = I (0-based I, so
/// a Slurm array `--array=0-(N-1)` or a Kubernetes indexed job's `JOB_COMPLETION_INDEX` fits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let hint = "expected I/N with 0 <= I < N, e.g. --shard 0/4 (I is 0-based: $SLURM_ARRAY_TASK_ID or $JOB_COMPLETION_INDEX)";
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("--shard {s:?}: {hint}"))?;
        let (Ok(i), Ok(n)) = (i.trim().parse::<usize>(), n.trim().parse::<usize>()) else {
            return Err(format!("--shard {s:?}: {hint}"));
        };
        if n == 0 || i >= n {
            return Err(format!("--shard {s:?}: {hint}"));
        }
        Ok(Shard { index: i, count: n })
    }
}

impl Shard {
    pub fn contains(&self, case: usize) -> bool {
        case % self.count == self.index
    }
}

/// FNV-1a, 64 bit: a hash that is the same on every platform and every build.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The splitmix64 finaliser: every input bit moves every output bit.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A case's folder name: a readable slug of the varied values (last key segment = value) and a
/// hash of the exact `KEY=VALUE` assignments, e.g. `radius=0.04_E=1e9-5f0c2a91`.
pub fn case_id(keys: &[String], values: &[String]) -> String {
    let mut slug = String::new();
    let mut canon = String::new();
    for (k, v) in keys.iter().zip(values) {
        canon.push_str(k);
        canon.push('=');
        canon.push_str(v);
        canon.push('\n');
        if !slug.is_empty() {
            slug.push('_');
        }
        let short = k.rsplit('.').next().unwrap_or(k);
        slug.push_str(&sanitize(short));
        slug.push('=');
        slug.push_str(&sanitize(v));
    }
    let mut slug: String = slug.chars().take(64).collect();
    if slug.is_empty() {
        slug.push_str("base");
    }
    format!("{slug}-{:08x}", mix(fnv1a(canon.as_bytes())) >> 32)
}

/// Letters, digits, `.`, `+`, `-`; everything else becomes `_`.
pub(crate) fn sanitize(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || ".+-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vary_lists_split_at_top_level_commas() {
        let v = parse_vary("obstacle.0.radius=0.05,0.04").unwrap();
        assert_eq!(v.key, "obstacle.0.radius");
        assert_eq!(v.values, ["0.05", "0.04"]);
        let v = parse_vary("rod.0.drive.acceleration=[-9.8,0],[-4.9, 0]").unwrap();
        assert_eq!(v.values, ["[-9.8,0]", "[-4.9, 0]"]);
        let v = parse_vary("solve.stepping=fixed,proximity").unwrap();
        assert_eq!(v.values, ["fixed", "proximity"]);
        assert!(parse_vary("rod.0.E").is_err());
        assert!(parse_vary("rod.0.E=1,,2").is_err());
        assert!(parse_vary("rod.0.E=1,1").is_err());
    }

    #[test]
    fn vary_ranges_are_clean_numbers() {
        assert_eq!(
            parse_vary("k=0.04:0.05:3").unwrap().values,
            ["0.04", "0.045", "0.05"]
        );
        assert_eq!(
            parse_vary("k=5:20:4").unwrap().values,
            ["5", "10", "15", "20"]
        );
        assert_eq!(
            parse_vary("k=1e6:1e9:4:log").unwrap().values,
            ["1000000.0", "10000000.0", "100000000.0", "1000000000.0"]
        );
        assert_eq!(parse_vary("k=0.1:0.2:1").unwrap().values, ["0.1"]);
        assert!(parse_vary("k=0:1:3:log").is_err());
        for v in parse_vary("k=0:1:7").unwrap().values {
            assert!(v.parse::<f64>().is_ok(), "{v}");
        }
    }

    #[test]
    fn shards_partition_the_grid() {
        let s: Shard = "1/3".parse().unwrap();
        assert_eq!(
            (0..7).filter(|k| s.contains(*k)).collect::<Vec<_>>(),
            [1, 4]
        );
        assert!("3/3".parse::<Shard>().is_err());
        assert!("1/0".parse::<Shard>().is_err());
        assert!("x".parse::<Shard>().is_err());
    }

    #[test]
    fn case_ids_are_stable_and_distinct() {
        let k = vec!["obstacle.0.radius".to_string(), "rod.0.E".to_string()];
        let a = case_id(&k, &["0.05".into(), "1e6".into()]);
        assert_eq!(a, case_id(&k, &["0.05".into(), "1e6".into()]));
        assert!(a.starts_with("radius=0.05_E=1e6-"), "{a}");
        assert_ne!(a, case_id(&k, &["0.05".into(), "1e9".into()]));
        // Same slug after sanitising, different assignments: the hash tells them apart.
        let k1 = vec!["a.x".to_string()];
        assert_ne!(
            case_id(&k1, &["[1,2]".into()]),
            case_id(&k1, &["[1_2]".into()])
        );
        assert_eq!(fnv1a(b"gripsim"), fnv1a(b"gripsim"));
    }
}
