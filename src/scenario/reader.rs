//! A TOML table reader that knows where it is, so every error names the file, the key path
//! and the offending value, and unknown keys get a "did you mean".

use std::cell::RefCell;
use toml::{Table, Value};

/// A scenario error: the file, the key path (dotted, as `--set` takes it), the value as written
/// and what is wrong, plus a hint for the fix when there is one.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioError {
    pub file: String,
    pub key: String,
    pub value: String,
    pub message: String,
    pub hint: Option<String>,
}

impl std::fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.file)?;
        if !self.key.is_empty() {
            write!(f, ": key `{}`", self.key)?;
        }
        if !self.value.is_empty() {
            write!(f, " = {}", self.value)?;
        }
        write!(f, ": {}", self.message)?;
        if let Some(h) = &self.hint {
            write!(f, " (hint: {h})")?;
        }
        Ok(())
    }
}

impl std::error::Error for ScenarioError {}

/// Short rendering of a TOML value for messages.
pub fn show(v: &Value) -> String {
    let s = match v {
        Value::String(s) => format!("{s:?}"),
        Value::Float(x) => {
            if x.is_nan() {
                "nan".into()
            } else if x.is_infinite() {
                if *x > 0.0 {
                    "inf".into()
                } else {
                    "-inf".into()
                }
            } else if *x != 0.0 && (x.abs() < 1e-4 || x.abs() >= 1e15) {
                // Exponent form for the very small and very large: 1e-300 stays "1e-300".
                format!("{x:e}")
            } else {
                // As TOML writes a float: 0.0 stays "0.0", not "0".
                let plain = format!("{x}");
                if plain.contains('.') {
                    plain
                } else {
                    format!("{plain}.0")
                }
            }
        }
        // Arrays and tables render inline; a multi-line rendering would break the one-line
        // error format.
        other => inline(other),
    };
    if s.chars().count() > 80 {
        let cut: String = s.chars().take(77).collect();
        format!("{cut}...")
    } else {
        s
    }
}

/// A value as TOML writes it inline (a datetime as written, not as the serializer's private
/// `$__toml_private_datetime` table).
fn inline(v: &Value) -> String {
    match v {
        Value::Datetime(d) => d.to_string(),
        Value::Array(a) => {
            let items: Vec<String> = a.iter().map(inline).collect();
            format!("[{}]", items.join(", "))
        }
        Value::Table(t) => {
            let items: Vec<String> = t
                .iter()
                .map(|(k, v)| format!("{k} = {}", inline(v)))
                .collect();
            format!("{{ {} }}", items.join(", "))
        }
        other => other.to_string().replace('\n', " "),
    }
}

pub(crate) fn type_name(v: &Value) -> &'static str {
    match v {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a float",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a datetime",
        Value::Array(_) => "an array",
        Value::Table(_) => "a table",
    }
}

/// Levenshtein distance, for "did you mean".
pub fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for i in 1..=a.len() {
        cur[0] = i;
        for j in 1..=b.len() {
            let cost = usize::from(!a[i - 1].eq_ignore_ascii_case(&b[j - 1]));
            cur[j] = (prev[j] + 1).min(cur[j - 1] + 1).min(prev[j - 1] + cost);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}

/// The closest of `candidates` to `word`, if it is close enough to be a likely typo.
pub fn did_you_mean<'a>(word: &str, candidates: &[&'a str]) -> Option<&'a str> {
    candidates
        .iter()
        .map(|c| (edit_distance(word, c), *c))
        .filter(|(d, c)| *d <= 2.max(c.len() / 3))
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// Reads one table. Remembers which keys were read so [`TableReader::finish`] can reject the rest.
pub struct TableReader<'a> {
    pub file: &'a str,
    pub path: String,
    pub table: &'a Table,
    used: RefCell<Vec<&'static str>>,
    known: &'static [&'static str],
}

impl<'a> TableReader<'a> {
    pub fn new(
        file: &'a str,
        path: String,
        table: &'a Table,
        known: &'static [&'static str],
    ) -> Self {
        Self {
            file,
            path,
            table,
            used: RefCell::new(Vec::new()),
            known,
        }
    }

    pub fn key_path(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_string()
        } else {
            format!("{}.{}", self.path, key)
        }
    }

    pub fn err(
        &self,
        key: &str,
        value: Option<&Value>,
        message: impl Into<String>,
    ) -> ScenarioError {
        ScenarioError {
            file: self.file.to_string(),
            key: self.key_path(key),
            value: value.map(show).unwrap_or_default(),
            message: message.into(),
            hint: None,
        }
    }

    pub fn err_hint(
        &self,
        key: &str,
        value: Option<&Value>,
        message: impl Into<String>,
        hint: impl Into<String>,
    ) -> ScenarioError {
        let mut e = self.err(key, value, message);
        e.hint = Some(hint.into());
        e
    }

    fn mark(&self, key: &'static str) {
        self.used.borrow_mut().push(key);
    }

    pub fn get(&self, key: &'static str) -> Option<&'a Value> {
        self.mark(key);
        self.table.get(key)
    }

    pub fn has(&self, key: &'static str) -> bool {
        self.table.contains_key(key)
    }

    pub fn required(&self, key: &'static str) -> Result<&'a Value, ScenarioError> {
        self.get(key).ok_or_else(|| {
            // A misspelt key is more useful to report than the missing one.
            if let Some(e) = self.typo_error(key) {
                return e;
            }
            self.err_hint(
                key,
                None,
                "missing required key",
                format!("add `{key} = ...` to [{}]", self.section_name()),
            )
        })
    }

    /// For a required `key` that is missing: the error for an unknown key of this table that
    /// looks like a misspelling of it, if there is one.
    pub fn typo_error(&self, key: &str) -> Option<ScenarioError> {
        if self.known.is_empty() {
            return None;
        }
        let mut keys: Vec<&String> = self.table.keys().collect();
        keys.sort();
        let typo = keys
            .into_iter()
            .map(|k| k.as_str())
            .filter(|k| *k != key && !self.known.contains(k))
            .find(|k| did_you_mean(k, &[key]).is_some())?;
        Some(self.err_hint(
            typo,
            self.table.get(typo),
            "unknown key",
            format!("did you mean `{key}`? (`{key}` is required here)"),
        ))
    }

    fn section_name(&self) -> String {
        if self.path.is_empty() {
            "the top level".into()
        } else {
            self.path.clone()
        }
    }

    /// A finite number (integers are accepted as numbers).
    pub fn num_value(&self, key: &str, v: &Value) -> Result<f64, ScenarioError> {
        let x = match v {
            Value::Float(x) => *x,
            Value::Integer(i) => *i as f64,
            other => {
                return Err(self.err(
                    key,
                    Some(other),
                    format!("expected a number, found {}", type_name(other)),
                ))
            }
        };
        if !x.is_finite() {
            return Err(self.err(
                key,
                Some(v),
                "must be a finite number (nan and inf are not allowed)",
            ));
        }
        Ok(x)
    }

    pub fn f64(&self, key: &'static str) -> Result<f64, ScenarioError> {
        let v = self.required(key)?;
        self.num_value(key, v)
    }

    pub fn opt_f64(&self, key: &'static str) -> Result<Option<f64>, ScenarioError> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => self.num_value(key, v).map(Some),
        }
    }

    pub fn f64_or(&self, key: &'static str, default: f64) -> Result<f64, ScenarioError> {
        Ok(self.opt_f64(key)?.unwrap_or(default))
    }

    /// A number that must be > 0.
    pub fn positive(&self, key: &'static str) -> Result<f64, ScenarioError> {
        let x = self.f64(key)?;
        self.check_positive(key, x)
    }

    pub fn check_positive(&self, key: &str, x: f64) -> Result<f64, ScenarioError> {
        if x <= 0.0 {
            // Show the value as written when it is in this table.
            let written = self.table.get(key).cloned().unwrap_or(Value::Float(x));
            return Err(self.err(key, Some(&written), "must be greater than zero"));
        }
        Ok(x)
    }

    pub fn opt_positive(&self, key: &'static str) -> Result<Option<f64>, ScenarioError> {
        match self.opt_f64(key)? {
            None => Ok(None),
            Some(x) => self.check_positive(key, x).map(Some),
        }
    }

    pub fn usize_value(&self, key: &str, v: &Value) -> Result<usize, ScenarioError> {
        match v {
            Value::Integer(i) if *i >= 0 => Ok(*i as usize),
            Value::Integer(_) => Err(self.err(key, Some(v), "must be a non-negative integer")),
            other => Err(self.err(
                key,
                Some(other),
                format!("expected an integer, found {}", type_name(other)),
            )),
        }
    }

    pub fn usize(&self, key: &'static str) -> Result<usize, ScenarioError> {
        let v = self.required(key)?;
        self.usize_value(key, v)
    }

    pub fn opt_usize(&self, key: &'static str) -> Result<Option<usize>, ScenarioError> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => self.usize_value(key, v).map(Some),
        }
    }

    pub fn str(&self, key: &'static str) -> Result<&'a str, ScenarioError> {
        let v = self.required(key)?;
        self.str_value(key, v)
    }

    pub fn str_value(&self, key: &str, v: &'a Value) -> Result<&'a str, ScenarioError> {
        match v {
            Value::String(s) => Ok(s.as_str()),
            other => Err(self.err(
                key,
                Some(other),
                format!("expected a string, found {}", type_name(other)),
            )),
        }
    }

    pub fn opt_str(&self, key: &'static str) -> Result<Option<&'a str>, ScenarioError> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => self.str_value(key, v).map(Some),
        }
    }

    pub fn opt_bool(&self, key: &'static str) -> Result<Option<bool>, ScenarioError> {
        match self.get(key) {
            None => Ok(None),
            Some(Value::Boolean(b)) => Ok(Some(*b)),
            Some(other) => Err(self.err(
                key,
                Some(other),
                format!("expected true or false, found {}", type_name(other)),
            )),
        }
    }

    pub fn vec2_value(&self, key: &str, v: &Value) -> Result<[f64; 2], ScenarioError> {
        match v {
            Value::Array(a) if a.len() == 2 => {
                let x = self
                    .num_value(&format!("{key}.0"), &a[0])
                    .map_err(|mut e| {
                        e.key = self.key_path(key);
                        e.value = show(v);
                        e
                    })?;
                let y = self
                    .num_value(&format!("{key}.1"), &a[1])
                    .map_err(|mut e| {
                        e.key = self.key_path(key);
                        e.value = show(v);
                        e
                    })?;
                Ok([x, y])
            }
            Value::Array(a) => Err(self.err(
                key,
                Some(v),
                format!("expected a 2D vector [x, y], found {} elements", a.len()),
            )),
            other => Err(self.err(
                key,
                Some(other),
                format!("expected a 2D vector [x, y], found {}", type_name(other)),
            )),
        }
    }

    pub fn vec2(&self, key: &'static str) -> Result<[f64; 2], ScenarioError> {
        let v = self.required(key)?;
        self.vec2_value(key, v)
    }

    pub fn opt_vec2(&self, key: &'static str) -> Result<Option<[f64; 2]>, ScenarioError> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => self.vec2_value(key, v).map(Some),
        }
    }

    pub fn array(&self, key: &'static str) -> Result<Option<&'a Vec<Value>>, ScenarioError> {
        match self.get(key) {
            None => Ok(None),
            Some(Value::Array(a)) => Ok(Some(a)),
            Some(other) => Err(self.err(
                key,
                Some(other),
                format!("expected an array, found {}", type_name(other)),
            )),
        }
    }

    /// A sub-table (inline or not), as a reader of its own.
    pub fn table(
        &self,
        key: &'static str,
        known: &'static [&'static str],
    ) -> Result<TableReader<'a>, ScenarioError> {
        let v = self.required(key)?;
        self.table_value(key, v, known)
    }

    pub fn opt_table(
        &self,
        key: &'static str,
        known: &'static [&'static str],
    ) -> Result<Option<TableReader<'a>>, ScenarioError> {
        match self.get(key) {
            None => Ok(None),
            Some(v) => self.table_value(key, v, known).map(Some),
        }
    }

    pub fn table_value(
        &self,
        key: &str,
        v: &'a Value,
        known: &'static [&'static str],
    ) -> Result<TableReader<'a>, ScenarioError> {
        match v {
            Value::Table(t) => Ok(TableReader::new(self.file, self.key_path(key), t, known)),
            other => Err(self.err(
                key,
                Some(other),
                format!("expected a table, found {}", type_name(other)),
            )),
        }
    }

    /// Reject keys nobody read, suggesting the nearest known one.
    pub fn finish(&self) -> Result<(), ScenarioError> {
        let used = self.used.borrow();
        let mut keys: Vec<&String> = self.table.keys().collect();
        keys.sort();
        for k in keys {
            if !used.iter().any(|u| u == k) {
                let v = self.table.get(k);
                if self.known.contains(&k.as_str()) {
                    // A key of this table, but not of the kind chosen.
                    return Err(match self.table.get("kind") {
                        Some(Value::String(kind)) => self.err_hint(
                            k,
                            v,
                            format!("not used when kind = {kind:?}"),
                            "remove it, or change `kind`",
                        ),
                        _ => self.err_hint(k, v, "not used here", "remove it"),
                    });
                }
                let mut e = self.err(k, v, "unknown key");
                let known = if self.known.is_empty() {
                    &used[..]
                } else {
                    self.known
                };
                e.hint = Some(match did_you_mean(k, known) {
                    Some(s) => format!("did you mean `{s}`?"),
                    None => format!("known keys here: {}", known.join(", ")),
                });
                return Err(e);
            }
        }
        Ok(())
    }
}
