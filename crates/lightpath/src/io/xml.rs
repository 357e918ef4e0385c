//! Reads an XML scene file into the property tree, resolving `<ref>` and `<include>`.
//!
//! Objects are elements (`<shape>`, `<camera>`, ...). Their attributes other than `type`,
//! `id` and `name` are properties, and so are typed property elements
//! (`<float name="fov" value="40"/>`). `<ref id="..."/>` stands for an object defined
//! earlier with that id (the same node, so it is built once); `<include
//! filename="..."/>` inserts the children of another file's root element.
//!
//! As in lightwave, a file may hold several top-level elements: objects defined at the
//! top level with an `id` (a `<scene id="scene">`, a shared `<bsdf>`) can be referred to
//! by the elements after them, such as the `<integrator>` that renders the scene.
//! A file with one top-level element reads as that element; with several, as a
//! [`DOCUMENT`] node that holds them in order.

use super::props::{Node, Property};
use crate::error::{Error, Location, Result};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// Elements whose `name` + `value` attributes form a property of the parent.
const PROPERTY_TAGS: &[&str] = &[
    "integer", "float", "string", "boolean", "bool", "vector", "color", "point", "rgb",
];

/// Tag of the node that holds the top-level elements of a file with several.
pub const DOCUMENT: &str = "#document";

/// Wraps the text in one element so that several top-level elements parse. The wrapper
/// takes a line of its own, and an XML declaration is blanked with spaces, so every other
/// character keeps its column and lies one row further down. `None` when the text has a
/// document type declaration (which cannot move inside an element).
fn wrap_top_level(text: &str) -> Option<String> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if text.contains("<!DOCTYPE") {
        return None;
    }
    let mut body = text.to_string();
    if body.trim_start().starts_with("<?xml") {
        let start = body.find("<?xml").unwrap_or(0);
        let end = body[start..].find("?>").map(|e| start + e + 2)?;
        let blank: String = body[start..end]
            .chars()
            .map(|c| if c == '\n' { '\n' } else { ' ' })
            .collect();
        body.replace_range(start..end, &blank);
    }
    Some(format!("<{WRAPPER}>\n{body}\n</{WRAPPER}>"))
}

/// The element [`wrap_top_level`] puts around a file's text. Errors never name it.
const WRAPPER: &str = "lightpath-document";

/// A parse error's row (in `text`, before wrapping), column and message. The wrapper
/// shows through in two errors, which are said in the file's own terms instead: an
/// element still open at the end of the file (the parser meets the wrapper's closing
/// tag, past the file's last line) and a closing tag that nothing opened (the parser
/// expected the wrapper's).
fn parse_error(e: &roxmltree::Error, text: &str, shift: u32) -> (u32, u32, String) {
    let pos = e.pos();
    let row = pos.row.saturating_sub(shift).max(1);
    if shift > 0 {
        if let roxmltree::Error::UnexpectedCloseTag(expected, actual, _) = e {
            if actual == WRAPPER {
                let last = text.lines().count().max(1) as u32;
                let col = text.lines().last().map_or(0, |l| l.chars().count()) as u32 + 1;
                return (
                    last,
                    col,
                    format!("the file ends before <{expected}> is closed"),
                );
            }
            if expected == WRAPPER {
                let message = format!("closing tag </{actual}> without an opening tag");
                return (row, pos.col, message);
            }
        }
    }
    // The message ends with the position, which is in the wrapped text.
    let message = e.to_string();
    let message = message
        .rsplit_once(" at ")
        .map_or(message.as_str(), |(m, _)| m)
        .to_string();
    (row, pos.col, message)
}

struct Reader {
    /// Rows the text being parsed was moved down by [`wrap_top_level`] (0 or 1).
    shift: u32,
    ids: HashMap<String, Rc<Node>>,
    /// Files being read, to reject include cycles.
    stack: Vec<PathBuf>,
    /// `$name` substitutions, longest names first so `$spp2` is not read as `$spp` + "2".
    defines: Vec<(String, String)>,
}

/// Parses `path` and returns its root element as a node.
pub fn read_file(path: &Path, defines: &[(String, String)]) -> Result<Rc<Node>> {
    let mut reader = Reader {
        shift: 0,
        ids: HashMap::new(),
        stack: Vec::new(),
        defines: sorted_defines(defines),
    };
    let root = reader.read(path, None)?;
    Ok(root)
}

/// Parses XML text as if it were the file `path` (relative paths resolve from there).
pub fn read_str(text: &str, path: &Path, defines: &[(String, String)]) -> Result<Rc<Node>> {
    let mut reader = Reader {
        shift: 0,
        ids: HashMap::new(),
        stack: Vec::new(),
        defines: sorted_defines(defines),
    };
    reader.parse(text, path)
}

impl Reader {
    fn read(&mut self, path: &Path, included_from: Option<&Location>) -> Result<Rc<Node>> {
        let text = std::fs::read_to_string(path).map_err(|e| match included_from {
            Some(loc) => Error::scene(
                loc.clone(),
                format!("cannot read included file {}: {e}", path.display()),
            ),
            None => Error::io(path, e),
        })?;
        let canonical = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
        if self.stack.contains(&canonical) {
            let loc = included_from
                .cloned()
                .unwrap_or_else(|| location(path, 0, 0));
            return Err(Error::scene(
                loc,
                format!("{} includes itself", path.display()),
            ));
        }
        self.stack.push(canonical);
        let node = self.parse(&text, path)?;
        self.stack.pop();
        Ok(node)
    }

    fn parse(&mut self, text: &str, path: &Path) -> Result<Rc<Node>> {
        let wrapped = wrap_top_level(text);
        let shift = wrapped.is_some() as u32;
        let doc = roxmltree::Document::parse(wrapped.as_deref().unwrap_or(text)).map_err(|e| {
            let (row, col, message) = parse_error(&e, text, shift);
            Error::scene(
                location(path, row, col),
                format!("malformed XML: {message}"),
            )
        })?;
        let outer = std::mem::replace(&mut self.shift, shift);
        let result = self.top_level(&doc, path);
        self.shift = outer;
        result
    }

    /// The file's only top-level element, or a [`DOCUMENT`] node holding all of them.
    fn top_level(&mut self, doc: &roxmltree::Document, path: &Path) -> Result<Rc<Node>> {
        if self.shift == 0 {
            return self.element(doc, doc.root_element(), path);
        }
        let wrapper = doc.root_element();
        let mut tops = Vec::new();
        for child in wrapper.children() {
            if child.is_text() {
                self.reject_text(doc, child, path)?;
            } else if child.is_element() {
                tops.push(child);
            }
        }
        match tops.as_slice() {
            [] => Err(Error::scene(
                location(path, 1, 1),
                "the file has no element",
            )),
            [only] => self.element(doc, *only, path),
            _ => {
                let mut node = Node::new(DOCUMENT, self.node_location(doc, tops[0], path));
                for el in tops {
                    node.children.push(self.element(doc, el, path)?);
                }
                Ok(Rc::new(node))
            }
        }
    }

    /// Text between elements must be whitespace.
    fn reject_text(
        &self,
        doc: &roxmltree::Document,
        text: roxmltree::Node,
        path: &Path,
    ) -> Result<()> {
        if text.text().is_some_and(|t| !t.trim().is_empty()) {
            return Err(Error::scene(
                self.node_location(doc, text, path),
                "unexpected text in scene file",
            ));
        }
        Ok(())
    }

    fn node_location(
        &self,
        doc: &roxmltree::Document,
        node: roxmltree::Node,
        path: &Path,
    ) -> Location {
        let pos = doc.text_pos_at(node.range().start);
        location(path, pos.row - self.shift, pos.col)
    }

    fn attr_location(
        &self,
        doc: &roxmltree::Document,
        attr: &roxmltree::Attribute,
        path: &Path,
    ) -> Location {
        let pos = doc.text_pos_at(attr.range().start);
        location(path, pos.row - self.shift, pos.col)
    }

    fn substitute(&self, value: &str) -> String {
        substitute(value, &self.defines)
    }

    fn element(
        &mut self,
        doc: &roxmltree::Document,
        el: roxmltree::Node,
        path: &Path,
    ) -> Result<Rc<Node>> {
        let loc = self.node_location(doc, el, path);
        let tag = el.tag_name().name();
        let mut node = Node::new(tag, loc.clone());
        for attr in el.attributes() {
            let value = self.substitute(attr.value());
            match attr.name() {
                "type" => node.type_name = Some(value),
                "id" => node.id = Some(value),
                "name" => node.name = Some(value),
                name => node.properties.push(Property {
                    name: name.to_string(),
                    value,
                    location: self.attr_location(doc, &attr, path),
                }),
            }
        }
        for child in el.children() {
            if child.is_text() {
                self.reject_text(doc, child, path)?;
                continue;
            }
            if !child.is_element() {
                continue;
            }
            let ctag = child.tag_name().name();
            let cloc = self.node_location(doc, child, path);
            if PROPERTY_TAGS.contains(&ctag) {
                let name = child.attribute("name").ok_or_else(|| {
                    Error::scene(cloc.clone(), format!("<{ctag}> needs a `name` attribute"))
                })?;
                let value = child.attribute("value").ok_or_else(|| {
                    Error::scene(
                        cloc.clone(),
                        format!("<{ctag} name=\"{name}\"> needs a `value` attribute"),
                    )
                })?;
                if let Some(a) = child
                    .attributes()
                    .find(|a| a.name() != "name" && a.name() != "value")
                {
                    return Err(Error::scene(
                        self.attr_location(doc, &a, path),
                        format!("unknown attribute `{}` on <{ctag}>", a.name()),
                    ));
                }
                node.properties.push(Property {
                    name: name.to_string(),
                    value: self.substitute(value),
                    location: cloc,
                });
            } else if ctag == "ref" {
                let id = child
                    .attribute("id")
                    .ok_or_else(|| Error::scene(cloc.clone(), "<ref> needs an `id` attribute"))?;
                let target = self.ids.get(id).ok_or_else(|| {
                    Error::scene(
                        cloc.clone(),
                        format!("<ref id=\"{id}\">: no object with this id is defined before"),
                    )
                })?;
                node.children.push(target.clone());
            } else if ctag == "include" {
                let file = child.attribute("filename").ok_or_else(|| {
                    Error::scene(cloc.clone(), "<include> needs a `filename` attribute")
                })?;
                let inc_path = resolve_path(path, &self.substitute(file));
                let inc = self.read(&inc_path, Some(&cloc))?;
                node.children.extend(inc.children.iter().cloned());
                node.properties.extend(inc.properties.iter().cloned());
            } else {
                let c = self.element(doc, child, path)?;
                node.children.push(c);
            }
        }
        let node = Rc::new(node);
        if let Some(id) = &node.id {
            self.ids.insert(id.clone(), node.clone());
        }
        Ok(node)
    }
}

/// Replaces every `$name` in `value`; `defines` must be sorted longest name first (see
/// [`sorted_defines`]) so that `$ab` is not taken for `$a` followed by `b`.
pub(crate) fn substitute(value: &str, defines: &[(String, String)]) -> String {
    if !value.contains('$') {
        return value.to_string();
    }
    let mut out = value.to_string();
    for (k, v) in defines {
        out = out.replace(&format!("${k}"), v);
    }
    out
}

/// The defines, longest name first, as [`substitute`] needs them.
pub(crate) fn sorted_defines(defines: &[(String, String)]) -> Vec<(String, String)> {
    let mut d = defines.to_vec();
    d.sort_by_key(|(k, _)| std::cmp::Reverse(k.len()));
    d
}

/// A path written in a scene file, relative to that file's folder.
pub fn resolve_path(scene_file: &Path, file: &str) -> PathBuf {
    let p = Path::new(file);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        scene_file.parent().unwrap_or(Path::new(".")).join(p)
    }
}

fn location(path: &Path, line: u32, column: u32) -> Location {
    Location {
        file: path.to_path_buf(),
        line,
        column,
    }
}
