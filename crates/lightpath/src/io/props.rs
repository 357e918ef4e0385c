//! The shared property tree that every XML scene dialect is parsed into.
//!
//! A [`Node`] is one scene object (`<shape type="sphere">`, `<camera>`, ...): its tag,
//! plugin type, id, properties (from XML attributes and from typed child elements such as
//! `<float name="fov" value="40"/>`) and child objects, each with its source location.
//! Builders *take* properties through the typed getters; a property nobody took is an
//! error ([`Node::check_all_used`]), so typos never pass silently.

use crate::error::{Error, Location, Result};
use crate::math::Vec3;
use std::cell::RefCell;
use std::collections::HashSet;
use std::rc::Rc;

/// One property: its raw text and where it was written.
#[derive(Debug, Clone)]
pub struct Property {
    pub name: String,
    pub value: String,
    pub location: Location,
}

/// A scene object in the property tree.
#[derive(Debug)]
pub struct Node {
    pub tag: String,
    pub type_name: Option<String>,
    pub id: Option<String>,
    /// The slot this object fills in its parent (`<texture name="albedo">`).
    pub name: Option<String>,
    pub location: Location,
    pub properties: Vec<Property>,
    pub children: Vec<Rc<Node>>,
    used: RefCell<HashSet<String>>,
    /// Every property name the builder asked for, present or not: the valid names, for
    /// suggesting one when a property is misspelt.
    asked: RefCell<HashSet<String>>,
}

impl Node {
    pub fn new(tag: &str, location: Location) -> Node {
        Node {
            tag: tag.to_string(),
            type_name: None,
            id: None,
            name: None,
            location,
            properties: Vec::new(),
            children: Vec::new(),
            used: RefCell::new(HashSet::new()),
            asked: RefCell::new(HashSet::new()),
        }
    }

    /// An error located at this node.
    pub fn error(&self, message: impl Into<String>) -> Error {
        Error::scene(self.location.clone(), message)
    }

    /// A readable name such as `<shape type="mesh">`.
    pub fn describe(&self) -> String {
        match &self.type_name {
            Some(t) => format!("<{} type=\"{}\">", self.tag, t),
            None => format!("<{}>", self.tag),
        }
    }

    /// The raw property, marking it used.
    pub fn take(&self, name: &str) -> Option<&Property> {
        self.asked.borrow_mut().insert(name.to_string());
        let p = self.properties.iter().rev().find(|p| p.name == name)?;
        self.used.borrow_mut().insert(name.to_string());
        Some(p)
    }

    pub fn has(&self, name: &str) -> bool {
        self.asked.borrow_mut().insert(name.to_string());
        self.properties.iter().any(|p| p.name == name)
    }

    pub fn string(&self, name: &str) -> Option<String> {
        self.take(name).map(|p| p.value.trim().to_string())
    }

    pub fn string_or(&self, name: &str, default: &str) -> String {
        self.string(name).unwrap_or_else(|| default.to_string())
    }

    pub fn float(&self, name: &str) -> Result<Option<f32>> {
        match self.take(name) {
            None => Ok(None),
            Some(p) => parse_float(&p.value).map(Some).ok_or_else(|| {
                Error::scene(
                    p.location.clone(),
                    format!("`{name}`: expected a number, got `{}`", p.value),
                )
            }),
        }
    }

    pub fn float_or(&self, name: &str, default: f32) -> Result<f32> {
        Ok(self.float(name)?.unwrap_or(default))
    }

    pub fn int(&self, name: &str) -> Result<Option<i64>> {
        match self.take(name) {
            None => Ok(None),
            Some(p) => p.value.trim().parse::<i64>().map(Some).map_err(|_| {
                Error::scene(
                    p.location.clone(),
                    format!("`{name}`: expected an integer, got `{}`", p.value),
                )
            }),
        }
    }

    pub fn bool_or(&self, name: &str, default: bool) -> Result<bool> {
        match self.take(name) {
            None => Ok(default),
            Some(p) => match p.value.trim() {
                "true" | "1" | "yes" => Ok(true),
                "false" | "0" | "no" => Ok(false),
                v => Err(Error::scene(
                    p.location.clone(),
                    format!("`{name}`: expected true or false, got `{v}`"),
                )),
            },
        }
    }

    /// A list of numbers separated by commas and/or whitespace.
    pub fn floats(&self, name: &str) -> Result<Option<Vec<f32>>> {
        match self.take(name) {
            None => Ok(None),
            Some(p) => parse_floats(&p.value).map(Some).ok_or_else(|| {
                Error::scene(
                    p.location.clone(),
                    format!("`{name}`: expected numbers, got `{}`", p.value),
                )
            }),
        }
    }

    /// A 3-vector: three numbers, or one number for all three components.
    pub fn vec3(&self, name: &str) -> Result<Option<Vec3>> {
        let Some(p) = self.take(name) else {
            return Ok(None);
        };
        match parse_floats(&p.value) {
            Some(v) if v.len() == 3 => Ok(Some(Vec3::new(v[0], v[1], v[2]))),
            Some(v) if v.len() == 1 => Ok(Some(Vec3::splat(v[0]))),
            Some(v) => Err(Error::scene(
                p.location.clone(),
                format!("`{name}`: expected 1 or 3 numbers, got {}", v.len()),
            )),
            None => Err(Error::scene(
                p.location.clone(),
                format!("`{name}`: expected numbers, got `{}`", p.value),
            )),
        }
    }

    /// Child objects with the given tag.
    pub fn children_tagged<'a>(&'a self, tag: &'a str) -> impl Iterator<Item = &'a Rc<Node>> + 'a {
        self.children.iter().filter(move |c| c.tag == tag)
    }

    /// Fails on the first property that no builder took.
    pub fn check_all_used(&self) -> Result<()> {
        let used = self.used.borrow();
        for p in &self.properties {
            if !used.contains(&p.name) {
                let mut known: Vec<String> = self.asked.borrow().iter().cloned().collect();
                known.sort();
                let known_refs: Vec<&str> = known.iter().map(String::as_str).collect();
                let hint = crate::io::suggest(&p.name, &known_refs)
                    .map(|s| format!(" (did you mean `{s}`?)"))
                    .unwrap_or_default();
                return Err(Error::scene(
                    p.location.clone(),
                    format!("unknown property `{}` on {}{hint}", p.name, self.describe()),
                ));
            }
        }
        Ok(())
    }
}

/// Parses one number, rejecting NaN and infinities.
pub fn parse_float(s: &str) -> Option<f32> {
    let v: f32 = s.trim().parse().ok()?;
    v.is_finite().then_some(v)
}

/// Parses numbers separated by commas and/or whitespace.
pub fn parse_floats(s: &str) -> Option<Vec<f32>> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(parse_float)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node() -> Node {
        let loc = Location {
            file: "x.xml".into(),
            line: 3,
            column: 5,
        };
        let mut n = Node::new("shape", loc.clone());
        n.type_name = Some("sphere".into());
        for (k, v) in [("a", "1, 2 3"), ("b", "2"), ("c", "nan"), ("d", "x")] {
            n.properties.push(Property {
                name: k.into(),
                value: v.into(),
                location: loc.clone(),
            });
        }
        n
    }

    #[test]
    fn typed_getters() {
        let n = node();
        assert_eq!(n.vec3("a").unwrap(), Some(Vec3::new(1.0, 2.0, 3.0)));
        assert_eq!(n.vec3("b").unwrap(), Some(Vec3::splat(2.0)));
        assert!(n.float("c").is_err(), "NaN is rejected");
        let e = n.float("d").unwrap_err().to_string();
        assert!(e.starts_with("x.xml:3:5:"), "{e}");
        assert_eq!(n.float("missing").unwrap(), None);
    }

    #[test]
    fn unused_properties_are_errors() {
        let n = node();
        n.take("a");
        n.take("b");
        n.take("c");
        let e = n.check_all_used().unwrap_err().to_string();
        assert!(
            e.contains("unknown property `d`") && e.contains("<shape type=\"sphere\">"),
            "{e}"
        );
        n.take("d");
        n.check_all_used().unwrap();
    }
}
