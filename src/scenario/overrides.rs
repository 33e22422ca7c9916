//! `--set KEY=VALUE`: override any scenario value by a dotted path (`obstacle.0.radius=0.04`,
//! `rod.0.E=1e9`, `solve.stepping=proximity`, `rod.1.drive.acceleration=[9.8,0]`).
//!
//! Every array on the path must exist; a missing table is created (`--set
//! contact.surface=face` on a scenario without `[contact]`) and the last key may be new (the
//! scenario reader then checks that they are known keys). The value is read as a TOML value, or as a string when
//! it is not one (so `solve.mode=static` needs no quotes).

use toml::{Table, Value};

/// (key, value, message, hint)
pub type OverrideError = (String, String, String, Option<String>);

/// Parse a `--set` value: a TOML value if it is one, else a bare string.
pub fn parse_value(s: &str) -> Value {
    let doc = format!("v = {s}");
    match doc.parse::<Table>() {
        Ok(mut t) => t
            .remove("v")
            .unwrap_or_else(|| Value::String(s.to_string())),
        Err(_) => Value::String(s.to_string()),
    }
}

pub fn apply(root: &mut Table, assignment: &str) -> Result<(), OverrideError> {
    let Some((path, raw)) = assignment.split_once('=') else {
        return Err((
            assignment.to_string(),
            String::new(),
            "expected KEY=VALUE".into(),
            Some("e.g. --set obstacle.0.radius=0.04".into()),
        ));
    };
    let path = path.trim();
    let raw = raw.trim();
    if raw.contains(['\n', '\r']) {
        // TOML would read the first line as the value and the rest as more keys, which
        // were then dropped without a word.
        return Err((
            path.to_string(),
            raw.escape_debug().to_string(),
            "a --set value must be on one line".into(),
            Some(
                "write line breaks inside a string as \\n, e.g. --set 'description=\"a\\nb\"'"
                    .into(),
            ),
        ));
    }
    if path.is_empty() {
        return Err((
            String::new(),
            raw.into(),
            "empty key".into(),
            Some("e.g. --set rod.0.E=1e9".into()),
        ));
    }
    let value = parse_value(raw);
    let parts: Vec<&str> = path.split('.').collect();
    let mut wrapped = Value::Table(std::mem::take(root));
    let result = set_path(&mut wrapped, &parts, value, raw);
    if let Value::Table(t) = wrapped {
        *root = t;
    }
    result
}

fn set_path(
    root: &mut Value,
    parts: &[&str],
    value: Value,
    raw: &str,
) -> Result<(), OverrideError> {
    let mut value = Some(value);
    let mut cur: &mut Value = root;
    let mut walked = String::new();
    for (i, part) in parts.iter().enumerate() {
        let last = i + 1 == parts.len();
        let here = if walked.is_empty() {
            part.to_string()
        } else {
            format!("{walked}.{part}")
        };
        match cur {
            Value::Table(t) => {
                if last {
                    t.insert(part.to_string(), value.take().unwrap());
                    return Ok(());
                }
                let index_next = parts[i + 1].parse::<usize>().is_ok();
                if !t.contains_key(*part) && !index_next {
                    // A table the scenario leaves out (e.g. `[contact]`): created empty; the
                    // scenario reader then checks its name and keys like any other.
                    t.insert(part.to_string(), Value::Table(Table::new()));
                }
                if !t.contains_key(*part) {
                    let known: Vec<&str> = t.keys().map(|k| k.as_str()).collect();
                    let hint = match super::reader::did_you_mean(part, &known) {
                        Some(m) => format!(
                            "did you mean `{}`?",
                            if walked.is_empty() {
                                m.to_string()
                            } else {
                                format!("{walked}.{m}")
                            }
                        ),
                        None => format!("keys here: {}", known.join(", ")),
                    };
                    return Err((
                        here,
                        raw.into(),
                        "this key does not exist in the scenario".into(),
                        Some(hint),
                    ));
                }
                cur = t.get_mut(*part).unwrap();
            }
            Value::Array(a) => {
                let Ok(idx) = part.parse::<usize>() else {
                    return Err((
                        here,
                        raw.into(),
                        format!(
                            "`{walked}` is an array: expected an index 0..{}",
                            a.len().saturating_sub(1)
                        ),
                        None,
                    ));
                };
                if idx >= a.len() {
                    return Err((
                        here,
                        raw.into(),
                        format!("index out of range: `{walked}` has {} entries", a.len()),
                        Some("indices are 0-based".into()),
                    ));
                }
                if last {
                    a[idx] = value.take().unwrap();
                    return Ok(());
                }
                cur = &mut a[idx];
            }
            _ => {
                return Err((
                    here,
                    raw.into(),
                    format!("`{walked}` is a value, not a table or array"),
                    None,
                ));
            }
        }
        walked = here;
    }
    Ok(())
}
