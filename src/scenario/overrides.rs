//! `--set KEY=VALUE`: override any scenario value by a dotted path (`obstacle.0.radius=0.04`,
//! `rod.0.E=1e9`, `solve.stepping=proximity`, `rod.1.drive.acceleration=[9.8,0]`).
//!
//! Every array on the path must exist; a missing table is created (`--set
//! contact.surface=face` on a scenario without `[contact]`) and the last key may be new (the
//! scenario reader then checks that they are known keys). `*` in place of an index sets the key
//! in every entry of the array: `rod.*.E=2e7` changes every prong. The value is read as a TOML value, or as a string when
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
    let result = set_path(&mut wrapped, &parts, value, raw, "");
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
    prefix: &str,
) -> Result<(), OverrideError> {
    let mut value = Some(value);
    let mut cur: &mut Value = root;
    let mut walked = prefix.to_string();
    for (i, part) in parts.iter().enumerate() {
        let last = i + 1 == parts.len();
        let here = if walked.is_empty() {
            part.to_string()
        } else {
            format!("{walked}.{part}")
        };
        match cur {
            Value::Table(_) if *part == "*" => {
                return Err((
                    here,
                    raw.into(),
                    format!("`{walked}` is a table, not an array: `*` stands for every entry of an array"),
                    None,
                ));
            }
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
            Value::Array(a) if *part == "*" => {
                return set_every(a, &parts[i + 1..], value.take().unwrap(), raw, &walked)
            }
            Value::Array(a) => {
                let Ok(idx) = part.parse::<usize>() else {
                    return Err((
                        here,
                        raw.into(),
                        format!(
                            "`{walked}` is an array: expected an index 0..{} or `*` (every entry)",
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

/// `KEY.*.REST=VALUE`: set `REST` in every entry of the array at `KEY` (`walked`).
fn set_every(
    a: &mut [Value],
    rest: &[&str],
    value: Value,
    raw: &str,
    walked: &str,
) -> Result<(), OverrideError> {
    let here = format!("{walked}.*");
    if rest.is_empty() {
        return Err((
            here,
            raw.into(),
            "`*` stands for every entry of an array and must be followed by a key".into(),
            Some(format!("e.g. --set {walked}.*.E=2e7")),
        ));
    }
    if a.is_empty() {
        return Err((here, raw.into(), format!("`{walked}` has no entries"), None));
    }
    for (k, entry) in a.iter_mut().enumerate() {
        set_path(entry, rest, value.clone(), raw, &format!("{walked}.{k}"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc() -> Table {
        "[[rod]]\nE = 1.0\n[[rod]]\nE = 1.0\nname = \"b\"\n[solve]\ndt = 1e-4\n"
            .parse()
            .unwrap()
    }

    #[test]
    fn a_star_sets_the_key_in_every_entry() {
        let mut t = doc();
        apply(&mut t, "rod.*.E=2e7").unwrap();
        for r in t["rod"].as_array().unwrap() {
            assert_eq!(r["E"].as_float(), Some(2e7));
        }
        apply(&mut t, "rod.*.section.kind=rect").unwrap();
        assert_eq!(t["rod"][1]["section"]["kind"].as_str(), Some("rect"));
    }

    #[test]
    fn a_star_out_of_place_is_an_error_naming_the_path() {
        let mut t = doc();
        let e = apply(&mut t, "rod.*=1").unwrap_err();
        assert_eq!(e.0, "rod.*");
        let e = apply(&mut t, "solve.*.dt=1").unwrap_err();
        assert_eq!(e.0, "solve.*", "{e:?}");
        // An error inside one entry names that entry.
        let e = apply(&mut t, "rod.*.E.x=1").unwrap_err();
        assert_eq!(e.0, "rod.0.E.x", "{e:?}");
        let mut empty: Table = "rod = []".parse().unwrap();
        let e = apply(&mut empty, "rod.*.E=1").unwrap_err();
        assert!(e.2.contains("no entries"), "{e:?}");
    }
}
