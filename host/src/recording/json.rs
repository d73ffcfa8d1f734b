//! Typed reading of a parsed JSON value that remembers where it is, so every type error names
//! its field (`frames[3].camera.fx: expected a number, found string`).

use super::error::Invalid;
use serde_json::{Map, Value};

/// A JSON value and its field path from the document root.
#[derive(Clone, Copy)]
pub(crate) struct At<'a> {
    value: &'a Value,
    path: &'a str,
}

/// Owned variant of [`At`] for child values whose path had to be built.
pub(crate) struct Child<'a> {
    value: &'a Value,
    path: String,
}

impl<'a> Child<'a> {
    /// Borrowed view.
    pub(crate) fn at(&self) -> At<'_> {
        At {
            value: self.value,
            path: &self.path,
        }
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

impl<'a> At<'a> {
    /// The document root (empty path).
    pub(crate) fn root(value: &'a Value) -> Self {
        At { value, path: "" }
    }

    /// This value's field path.
    pub(crate) fn path(&self) -> &str {
        if self.path.is_empty() {
            "(root)"
        } else {
            self.path
        }
    }

    /// A problem with this field.
    pub(crate) fn invalid(&self, message: impl std::fmt::Display) -> Invalid {
        Invalid::new(self.path(), message)
    }

    fn expected(&self, what: &str) -> Invalid {
        self.invalid(format_args!("expected {what}, found {}", kind(self.value)))
    }

    fn key_path(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_string()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    /// Checks this is an object whose keys are all in `allowed`.
    pub(crate) fn object(&self, allowed: &[&str]) -> Result<&'a Map<String, Value>, Invalid> {
        let map = self
            .value
            .as_object()
            .ok_or_else(|| self.expected("an object"))?;
        if let Some(k) = map.keys().find(|k| !allowed.contains(&k.as_str())) {
            return Err(Invalid::new(
                self.key_path(k),
                format_args!("unknown field (expected one of: {})", allowed.join(", ")),
            ));
        }
        Ok(map)
    }

    /// An optional member of this object (absent and `null` both give `None`).
    pub(crate) fn get(&self, key: &str) -> Option<Child<'a>> {
        match self.value.get(key) {
            None | Some(Value::Null) => None,
            Some(value) => Some(Child {
                value,
                path: self.key_path(key),
            }),
        }
    }

    /// A required member of this object.
    pub(crate) fn req(&self, key: &str) -> Result<Child<'a>, Invalid> {
        self.get(key)
            .ok_or_else(|| Invalid::new(self.key_path(key), "missing"))
    }

    /// The elements of this array, each with its indexed path.
    pub(crate) fn array(&self) -> Result<Vec<Child<'a>>, Invalid> {
        let items = self
            .value
            .as_array()
            .ok_or_else(|| self.expected("an array"))?;
        Ok(items
            .iter()
            .enumerate()
            .map(|(i, value)| Child {
                value,
                path: format!("{}[{i}]", self.path),
            })
            .collect())
    }

    /// This array, which must hold exactly `N` elements, each read by `f`.
    pub(crate) fn fixed<T: Copy + Default, const N: usize>(
        &self,
        f: impl Fn(At<'_>) -> Result<T, Invalid>,
    ) -> Result<[T; N], Invalid> {
        let items = self.array()?;
        if items.len() != N {
            return Err(self.invalid(format_args!("expected {N} values, found {}", items.len())));
        }
        let mut out = [T::default(); N];
        for (o, item) in out.iter_mut().zip(&items) {
            *o = f(item.at())?;
        }
        Ok(out)
    }

    /// A string.
    pub(crate) fn str(&self) -> Result<&'a str, Invalid> {
        self.value.as_str().ok_or_else(|| self.expected("a string"))
    }

    /// A boolean.
    pub(crate) fn bool(&self) -> Result<bool, Invalid> {
        self.value
            .as_bool()
            .ok_or_else(|| self.expected("true or false"))
    }

    /// Any JSON number as f64 (finiteness is checked by validation, not here).
    pub(crate) fn f64(&self) -> Result<f64, Invalid> {
        self.value.as_f64().ok_or_else(|| self.expected("a number"))
    }

    /// A number stored as f32 (values beyond f32 become infinite and fail validation).
    pub(crate) fn f32(&self) -> Result<f32, Invalid> {
        self.f64().map(|x| x as f32)
    }

    /// A non-negative integer no larger than `max`.
    pub(crate) fn uint(&self, max: u64) -> Result<u64, Invalid> {
        match self.value.as_u64() {
            Some(x) if x <= max => Ok(x),
            _ if self.value.is_number() => Err(self.invalid(format_args!(
                "expected an integer in 0..={max}, found {}",
                self.value
            ))),
            _ => Err(self.expected("an integer")),
        }
    }

    /// An array of numbers as f32, `field[i]` named on error.
    pub(crate) fn f32_vec(&self) -> Result<Vec<f32>, Invalid> {
        self.array()?.iter().map(|c| c.at().f32()).collect()
    }
}
