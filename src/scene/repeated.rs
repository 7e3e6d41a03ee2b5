//! Names repeated within one JSON object. RFC 8259 says the names of an object SHOULD be
//! unique and leaves what a repeated one means to the reader; `serde_json::Value` keeps the
//! last. A job document with `"order": 1, …, "order": 3` is almost surely a mistake, so it is
//! refused, at the path of the repeat, rather than solved with one of the two. Written here
//! because the check needs the text: the parsed value no longer holds the first occurrence.

use super::walk::{child, index};
use super::FieldError;
use serde::de::{DeserializeSeed, Deserializer, MapAccess, SeqAccess, Visitor};
use std::collections::HashMap;
use std::fmt;

/// The most repeated names reported for one document.
const MAX_REPORTED: usize = 100;

/// Every repeated name in the JSON `text` (each once per object, at most [`MAX_REPORTED`]),
/// at its JSON pointer, in document order. A text that is not JSON has none (its parse
/// reports it).
pub(crate) fn repeated_keys(text: &str) -> Vec<FieldError> {
    let mut found = Vec::new();
    let mut de = serde_json::Deserializer::from_str(text);
    let walk = Walk {
        path: String::new(),
        found: &mut found,
    };
    if walk.deserialize(&mut de).is_err() {
        return Vec::new();
    }
    found
}

/// One value at `path`; the repeats below it go to `found`.
struct Walk<'a> {
    path: String,
    found: &'a mut Vec<FieldError>,
}

impl<'de> DeserializeSeed<'de> for Walk<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Walk<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_bool<E: serde::de::Error>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_i64<E: serde::de::Error>(self, _: i64) -> Result<(), E> {
        Ok(())
    }
    fn visit_u64<E: serde::de::Error>(self, _: u64) -> Result<(), E> {
        Ok(())
    }
    fn visit_f64<E: serde::de::Error>(self, _: f64) -> Result<(), E> {
        Ok(())
    }
    fn visit_str<E: serde::de::Error>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E: serde::de::Error>(self) -> Result<(), E> {
        Ok(())
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut i = 0;
        loop {
            let item = Walk {
                path: index(&self.path, i),
                found: &mut *self.found,
            };
            if seq.next_element_seed(item)?.is_none() {
                return Ok(());
            }
            i += 1;
        }
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        // each name once, whatever the number of its repeats
        let mut seen = HashMap::new();
        while let Some(key) = map.next_key::<String>()? {
            let path = child(&self.path, &key);
            let times = seen.entry(key.clone()).or_insert(0u32);
            *times += 1;
            if *times == 2 && self.found.len() < MAX_REPORTED {
                self.found.push(FieldError {
                    path: path.clone(),
                    message: format!(
                        "\"{key}\" is given more than once in this object; give each name once"
                    ),
                });
            }
            map.next_value_seed(Walk {
                path,
                found: &mut *self.found,
            })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeats_are_found_at_their_paths() {
        let text = r#"{"scene": {"surfaces": [{"name": "a", "rho": 1, "name": "b"}, {"a/b": 1, "a/b": 2}]},
                       "solver": {"order": 1, "order": 3}, "output": {}}"#;
        let found = repeated_keys(text);
        let paths: Vec<&str> = found.iter().map(|e| e.path.as_str()).collect();
        assert_eq!(
            paths,
            [
                "/scene/surfaces/0/name",
                "/scene/surfaces/1/a~1b",
                "/solver/order"
            ]
        );
        assert!(found[2]
            .message
            .contains("\"order\" is given more than once"));
        // a name given many times is reported once; many names, at most MAX_REPORTED
        let many = format!("{{{}}}", vec!["\"a\": 0"; 1000].join(","));
        assert_eq!(repeated_keys(&many).len(), 1);
        let names: Vec<String> = (0..1000)
            .map(|i| format!("\"k{i}\": 0, \"k{i}\": 1"))
            .collect();
        let found = repeated_keys(&format!("{{{}}}", names.join(",")));
        assert_eq!(found.len(), MAX_REPORTED);
        assert_eq!(found[0].path, "/k0");
    }

    #[test]
    fn unique_names_and_non_json_have_none() {
        assert!(repeated_keys(r#"{"a": {"a": [{"a": 1}, {"a": 2}]}, "b": null}"#).is_empty());
        assert!(repeated_keys("{\"a\": 1, \"a\"").is_empty());
        assert!(repeated_keys("[1, 2, 3]").is_empty());
    }
}
