//! `--set FIELD=VALUE` typed by the field it replaces: the scenario is written out as RON (enum
//! variants keep their names there, unlike in an untyped tree), the value at the dotted path is found
//! by a small scanner of RON's value grammar and replaced by the given text, and the whole is read back
//! with the scenario's own types. So a whole enum value (`boundaries.1.shape=Sphere(centre: (0, 0,
//! 0.1), radius: 0.01)`, `boundaries.0.motion=Translate(velocity: (0, 0, -0.1))`) or a list of them
//! (`numerics.liquid_tension_in=[Box(min: …, max: …)]`) can be given; `Scenario::with_override` falls
//! back to its untyped route for the shorthands RON itself refuses (a bare number for an `Option`).
//!
//! Paths as for the untyped route: struct fields by name, list entries by index, and a named wrapper —
//! an enum variant such as `Box(…)`, or `Some(…)` — stepped through without being named.

use std::ops::Range;

/// `text` (RON of one value) with the value at `path` replaced by `value`.
pub fn splice(text: &str, path: &str, value: &str) -> Result<String, String> {
    let span = locate(text, path)?;
    Ok(format!("{}{}{}", &text[..span.start], value, &text[span.end..]))
}

/// Byte range of the value at the dotted `path` in `text`.
pub fn locate(text: &str, path: &str) -> Result<Range<usize>, String> {
    let s = Scanner { t: text, b: text.as_bytes() };
    let mut pos = s.ws(0);
    for seg in path.split('.') {
        pos = s.child(pos, seg)?;
    }
    Ok(pos..s.value_end(pos)?)
}

struct Scanner<'a> {
    t: &'a str,
    b: &'a [u8],
}

/// One entry of a bracketed group: its field name or map key (if any) and where its value starts.
struct Entry<'a> {
    key: Option<&'a str>,
    value: usize,
}

fn is_ident_start(c: u8) -> bool {
    c.is_ascii_alphabetic() || c == b'_'
}

fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

impl<'a> Scanner<'a> {
    fn ws(&self, mut i: usize) -> usize {
        while i < self.b.len() && self.b[i].is_ascii_whitespace() {
            i += 1;
        }
        i
    }

    fn ident_end(&self, mut i: usize) -> usize {
        while i < self.b.len() && is_ident(self.b[i]) {
            i += 1;
        }
        i
    }

    /// End (exclusive) of the string literal starting at `i` (a `"`).
    fn string_end(&self, mut i: usize) -> Result<usize, String> {
        i += 1;
        while i < self.b.len() {
            match self.b[i] {
                b'\\' => i += 2,
                b'"' => return Ok(i + 1),
                _ => i += 1,
            }
        }
        Err("unterminated string in the scenario's RON".into())
    }

    /// End (exclusive) of the value starting at `i`.
    fn value_end(&self, i: usize) -> Result<usize, String> {
        match self.b.get(i) {
            None => Err("unexpected end of the scenario's RON".into()),
            Some(b'"') => self.string_end(i),
            Some(b'(' | b'[' | b'{') => {
                let mut depth = 0usize;
                let mut k = i;
                while k < self.b.len() {
                    match self.b[k] {
                        b'"' => {
                            k = self.string_end(k)?;
                            continue;
                        }
                        b'(' | b'[' | b'{' => depth += 1,
                        b')' | b']' | b'}' => {
                            depth -= 1;
                            if depth == 0 {
                                return Ok(k + 1);
                            }
                        }
                        _ => {}
                    }
                    k += 1;
                }
                Err("unbalanced brackets in the scenario's RON".into())
            }
            Some(&c) if is_ident_start(c) => {
                let e = self.ident_end(i);
                let j = self.ws(e);
                if self.b.get(j) == Some(&b'(') { self.value_end(j) } else { Ok(e) }
            }
            Some(_) => {
                let mut k = i;
                while k < self.b.len() && !matches!(self.b[k], b',' | b')' | b']' | b'}' | b':') {
                    k += 1;
                }
                Ok(k)
            }
        }
    }

    /// Whether the group opened at `open` holds `name: value` fields.
    fn has_fields(&self, open: usize) -> bool {
        let i = self.ws(open + 1);
        if !self.b.get(i).is_some_and(|&c| is_ident_start(c)) {
            return false;
        }
        let j = self.ws(self.ident_end(i));
        self.b.get(j) == Some(&b':')
    }

    /// The entries of the group opened at `open` (`(`, `[` or `{`).
    fn entries(&self, open: usize) -> Result<Vec<Entry<'a>>, String> {
        let fields = self.b[open] == b'(' && self.has_fields(open);
        let map = self.b[open] == b'{';
        let mut out = Vec::new();
        let mut i = self.ws(open + 1);
        loop {
            match self.b.get(i) {
                None => return Err("unbalanced brackets in the scenario's RON".into()),
                Some(b')' | b']' | b'}') => return Ok(out),
                _ => {}
            }
            let key = if fields || map {
                let e = if map { self.value_end(i)? } else { self.ident_end(i) };
                let k = self.t[i..e].trim_matches('"');
                i = self.ws(e);
                if self.b.get(i) != Some(&b':') {
                    return Err("expected `:` in the scenario's RON".into());
                }
                i = self.ws(i + 1);
                Some(k)
            } else {
                None
            };
            out.push(Entry { key, value: i });
            i = self.ws(self.value_end(i)?);
            if self.b.get(i) == Some(&b',') {
                i = self.ws(i + 1);
            }
        }
    }

    /// Where the child `seg` of the value at `i` starts.
    fn child(&self, i: usize, seg: &str) -> Result<usize, String> {
        match self.b.get(i) {
            Some(&c) if is_ident_start(c) => {
                let e = self.ident_end(i);
                let open = self.ws(e);
                if self.b.get(open) != Some(&b'(') {
                    return Err(format!("`{seg}` goes below a plain value"));
                }
                if &self.t[i..e] == seg {
                    return Ok(open); // the variant named in the path: its parenthesised part
                }
                let inner = self.entries(open)?;
                // a wrapper around one unnamed value (`Some(x)`, a newtype variant) is transparent
                match inner.as_slice() {
                    [Entry { key: None, value }] => self.child(*value, seg),
                    _ => self.pick(&inner, seg),
                }
            }
            Some(b'(' | b'[' | b'{') => self.pick(&self.entries(i)?, seg),
            _ => Err(format!("`{seg}` goes below a plain value")),
        }
    }

    fn pick(&self, entries: &[Entry<'a>], seg: &str) -> Result<usize, String> {
        if entries.iter().any(|e| e.key.is_some()) {
            return entries
                .iter()
                .find(|e| e.key == Some(seg))
                .map(|e| e.value)
                .ok_or_else(|| format!("no field `{seg}` here"));
        }
        let k: usize = seg.parse().map_err(|_| format!("`{seg}` is not a list index"))?;
        let n = entries.len();
        entries.get(k).map(|e| e.value).ok_or_else(|| format!("index {k} out of range (list has {n} entries)"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: &str = r#"(name: "a, (b)", shapes: [Box(min: (0.0, 1.0, 2.0), max: (3.0, 4.0, 5.0)), Sphere(centre: (1.0, 1.0, 1.0), radius: 0.5)], opt: Some((x: 1.5, y: None)), flow: Constant(2.0), motion: Static, empty: [])"#;

    fn at(path: &str) -> &'static str {
        let r = locate(T, path).unwrap_or_else(|e| panic!("{path}: {e}"));
        &T[r]
    }

    #[test]
    fn finds_fields_entries_and_steps_through_wrappers() {
        assert_eq!(at("name"), r#""a, (b)""#);
        assert_eq!(at("shapes.0"), "Box(min: (0.0, 1.0, 2.0), max: (3.0, 4.0, 5.0))");
        assert_eq!(at("shapes.0.max"), "(3.0, 4.0, 5.0)");
        assert_eq!(at("shapes.0.max.2"), "5.0");
        assert_eq!(at("shapes.1.radius"), "0.5");
        assert_eq!(at("shapes.1.Sphere"), "(centre: (1.0, 1.0, 1.0), radius: 0.5)");
        assert_eq!(at("opt"), "Some((x: 1.5, y: None))");
        assert_eq!(at("opt.x"), "1.5");
        assert_eq!(at("opt.y"), "None");
        assert_eq!(at("flow"), "Constant(2.0)");
        assert_eq!(at("motion"), "Static");
        assert_eq!(at("empty"), "[]");
        let s = splice(T, "shapes.0", "Sphere(centre: (0.0, 0.0, 0.0), radius: 1.0)").expect("splice");
        assert!(s.contains("shapes: [Sphere(centre: (0.0, 0.0, 0.0), radius: 1.0), Sphere("), "{s}");
    }

    #[test]
    fn says_what_is_wrong_with_a_path() {
        assert_eq!(locate(T, "nonsense").unwrap_err(), "no field `nonsense` here");
        assert_eq!(locate(T, "shapes.7").unwrap_err(), "index 7 out of range (list has 2 entries)");
        assert_eq!(locate(T, "shapes.x").unwrap_err(), "`x` is not a list index");
        assert_eq!(locate(T, "motion.speed").unwrap_err(), "`speed` goes below a plain value");
        assert_eq!(locate(T, "shapes.1.radius.0").unwrap_err(), "`0` goes below a plain value");
    }
}
