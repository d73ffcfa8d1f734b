//! Naming the field behind a serde error: serde's messages for a wrong type (`invalid type:
//! string "x", expected u16`) or a missing field do not say where in the document the value
//! is. [`locate`] finds it by grafting the document's values, one leaf at a time, onto a known
//! good document of the same type and seeing which graft the type refuses.

use serde::de::DeserializeOwned;
use serde_json::Value;

/// The JSON path (`grid.rows`, `grid.ifov[1]`, `dark.p_losss`) of the first value of `doc`
/// that `T` refuses once grafted onto `base` (a document `T` accepts), or of the member that
/// `message` (serde's error) says is missing. `None` when no single value is to blame.
pub(crate) fn locate<T: DeserializeOwned>(
    base: &Value,
    doc: &Value,
    message: &str,
) -> Option<String> {
    let mut path = Vec::new();
    if let Some(p) = graft_walk::<T>(base, doc, &mut path) {
        return Some(p);
    }
    let missing = message
        .strip_prefix("missing field `")
        .and_then(|rest| rest.split('`').next())?;
    missing_walk(base, doc, missing, &mut Vec::new())
}

/// Merges `patch` into `base` field by field: members of a JSON object in `patch` replace or
/// merge into (when both are objects) the member of the same name in `base`; any other value
/// (numbers, strings, arrays, `null`) replaces `base`'s wholesale. Members `base` lacks are added,
/// so that the type's own deserialisation refuses them as unknown fields.
pub(crate) fn merge(base: &mut Value, patch: &Value) {
    match (base, patch) {
        (Value::Object(b), Value::Object(p)) => {
            for (k, v) in p {
                match b.get_mut(k) {
                    Some(slot) => merge(slot, v),
                    None => {
                        b.insert(k.clone(), v.clone());
                    }
                }
            }
        }
        (slot, v) => *slot = v.clone(),
    }
}

/// One step of a JSON path.
#[derive(Clone)]
enum Step {
    Key(String),
    Index(usize),
}

fn render(path: &[Step]) -> String {
    let mut s = String::new();
    for step in path {
        match step {
            Step::Key(k) if s.is_empty() => s.push_str(k),
            Step::Key(k) => {
                s.push('.');
                s.push_str(k);
            }
            Step::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    if s.is_empty() {
        "(root)".into()
    } else {
        s
    }
}

/// `base` with the value at `path` replaced by `v` (objects created on the way).
fn graft(base: &Value, path: &[Step], v: &Value) -> Value {
    let mut out = base.clone();
    let mut at = &mut out;
    for step in path {
        at = match step {
            Step::Key(k) => {
                if !at.is_object() {
                    *at = Value::Object(Default::default());
                }
                at.as_object_mut()
                    .map(|m| m.entry(k.clone()).or_insert(Value::Null))
                    .expect("made an object above")
            }
            Step::Index(i) => match at.as_array_mut() {
                Some(a) if *i < a.len() => &mut a[*i],
                _ => return out,
            },
        };
    }
    *at = v.clone();
    out
}

fn refused<T: DeserializeOwned>(v: Value) -> bool {
    serde_json::from_value::<T>(v).is_err()
}

fn graft_walk<T: DeserializeOwned>(
    base: &Value,
    doc: &Value,
    path: &mut Vec<Step>,
) -> Option<String> {
    let base_here = lookup(base, path);
    match (doc, base_here) {
        (Value::Object(m), Some(Value::Object(_))) => {
            for (k, v) in m {
                path.push(Step::Key(k.clone()));
                let found = graft_walk::<T>(base, v, path);
                path.pop();
                if found.is_some() {
                    return found;
                }
            }
            None
        }
        _ => {
            if !refused::<T>(graft(base, path, doc)) {
                return None;
            }
            // Name the element of an array of the expected length.
            if let (Value::Array(items), Some(Value::Array(b))) = (doc, base_here) {
                if items.len() == b.len() {
                    for (i, item) in items.iter().enumerate() {
                        path.push(Step::Index(i));
                        let bad = refused::<T>(graft(base, path, item));
                        let name = render(path);
                        path.pop();
                        if bad {
                            return Some(name);
                        }
                    }
                }
            }
            Some(render(path))
        }
    }
}

fn lookup<'a>(v: &'a Value, path: &[Step]) -> Option<&'a Value> {
    let mut at = v;
    for step in path {
        at = match step {
            Step::Key(k) => at.get(k)?,
            Step::Index(i) => at.get(*i)?,
        };
    }
    Some(at)
}

fn missing_walk(base: &Value, doc: &Value, key: &str, path: &mut Vec<Step>) -> Option<String> {
    let (Value::Object(b), Value::Object(d)) = (base, doc) else {
        return None;
    };
    if b.contains_key(key) && !d.contains_key(key) {
        path.push(Step::Key(key.to_string()));
        return Some(render(path));
    }
    for (k, dv) in d {
        if let Some(bv) = b.get(k) {
            path.push(Step::Key(k.clone()));
            let found = missing_walk(bv, dv, key, path);
            path.pop();
            if found.is_some() {
                return found;
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Inner {
        n: u16,
        pair: [f32; 2],
    }

    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Outer {
        inner: Inner,
        flag: bool,
    }

    fn find(doc: &str) -> Option<String> {
        let base: Value =
            serde_json::from_str(r#"{"inner": {"n": 1, "pair": [1, 2]}, "flag": true}"#).unwrap();
        let doc: Value = serde_json::from_str(doc).unwrap();
        let msg = serde_json::from_value::<Outer>(doc.clone())
            .err()
            .unwrap()
            .to_string();
        locate::<Outer>(&base, &doc, &msg)
    }

    #[test]
    fn merge_replaces_leaves_and_recurses_into_objects() {
        let mut base: Value =
            serde_json::from_str(r#"{"inner": {"n": 1, "pair": [1, 2]}, "flag": true}"#).unwrap();
        let patch: Value = serde_json::from_str(r#"{"inner": {"pair": [3]}, "x": 0}"#).unwrap();
        merge(&mut base, &patch);
        let want: Value =
            serde_json::from_str(r#"{"inner": {"n": 1, "pair": [3]}, "flag": true, "x": 0}"#)
                .unwrap();
        assert_eq!(base, want);
    }

    #[test]
    fn names_wrong_types_unknown_and_missing_fields() {
        let f = |s: &str| find(s).unwrap();
        assert_eq!(
            f(r#"{"inner": {"n": "x", "pair": [1, 2]}, "flag": true}"#),
            "inner.n"
        );
        assert_eq!(
            f(r#"{"inner": {"n": 70000, "pair": [1, 2]}, "flag": true}"#),
            "inner.n"
        );
        assert_eq!(
            f(r#"{"inner": {"n": 1, "pair": [1, "2"]}, "flag": true}"#),
            "inner.pair[1]"
        );
        assert_eq!(
            f(r#"{"inner": {"n": 1, "pair": [1]}, "flag": true}"#),
            "inner.pair"
        );
        assert_eq!(
            f(r#"{"inner": {"n": 1, "pair": [1, 2], "m": 0}, "flag": true}"#),
            "inner.m"
        );
        assert_eq!(f(r#"{"inner": {"pair": [1, 2]}, "flag": true}"#), "inner.n");
        assert_eq!(f(r#"{"inner": 3, "flag": true}"#), "inner");
        assert_eq!(f(r#"{"inner": {"n": 1, "pair": [1, 2]}}"#), "flag");
    }
}
