//! Just enough of XML to find a URDF's top-level `<joint>` elements and their `<origin>` by byte
//! span, so an export can replace those spans and leave every other byte of the file alone.
//! Comments, processing instructions, CDATA and `<!…>` declarations are skipped (xacro output
//! carries whole commented-out elements).

use std::ops::Range;

/// One tag of the document.
#[derive(Debug, Clone)]
struct Tag {
    name: String,
    span: Range<usize>,
    closing: bool,
    self_closing: bool,
}

/// A top-level `<joint>` of the robot: its name, the span of its start tag and of its
/// `<origin>` (the whole element when it is not self-closing), if it has one.
#[derive(Debug, Clone)]
pub(crate) struct JointSpans {
    /// The joint's `name` attribute, entities decoded.
    pub name: String,
    /// The `<joint …>` start tag.
    pub start_tag: Range<usize>,
    /// The `<origin …/>` element.
    pub origin: Option<Range<usize>>,
}

/// Every top-level joint (a direct child of `<robot>`) with its spans; `None` when the text
/// is not well-formed enough to scan (an unterminated tag or comment).
pub(crate) fn joints(text: &str) -> Option<(Vec<JointSpans>, usize)> {
    let tags = tags(text)?;
    let mut depth = 0usize;
    let mut out = Vec::new();
    let mut current: Option<JointSpans> = None;
    let mut robot_end = None;
    for t in &tags {
        if t.closing {
            depth = depth.checked_sub(1)?;
            if depth == 1 && t.name == "joint" {
                out.extend(current.take());
            }
            if depth == 0 && t.name == "robot" {
                robot_end = Some(t.span.start);
            }
            continue;
        }
        if depth == 1 && t.name == "joint" {
            let name = attribute(&text[t.span.clone()], "name").unwrap_or_default();
            let j = JointSpans {
                name,
                start_tag: t.span.clone(),
                origin: None,
            };
            if t.self_closing {
                out.push(j);
            } else {
                current = Some(j);
            }
        } else if depth == 2 && t.name == "origin" {
            if let Some(j) = current.as_mut() {
                j.origin = Some(t.span.clone());
            }
        }
        if !t.self_closing {
            depth += 1;
        }
    }
    // A non-self-closing <origin> spans to its end tag: widen those spans.
    for j in &mut out {
        if let Some(o) = j.origin.clone() {
            if !text[o.clone()].ends_with("/>") {
                let rest = &text[o.end..];
                let close = rest.find("</origin>")?;
                j.origin = Some(o.start..o.end + close + "</origin>".len());
            }
        }
    }
    Some((out, robot_end?))
}

fn tags(text: &str) -> Option<Vec<Tag>> {
    let b = text.as_bytes();
    let mut i = 0;
    let mut out = Vec::new();
    while let Some(off) = text[i..].find('<') {
        let start = i + off;
        let rest = &text[start..];
        let skip = [
            ("<!--", "-->"),
            ("<![CDATA[", "]]>"),
            ("<?", "?>"),
            ("<!", ">"),
        ]
        .iter()
        .find(|(open, _)| rest.starts_with(open));
        if let Some((open, close)) = skip {
            let end = rest[open.len()..].find(close)? + open.len() + close.len();
            i = start + end;
            continue;
        }
        let mut j = start + 1;
        let mut quote = None;
        while j < b.len() {
            match (quote, b[j]) {
                (None, b'"' | b'\'') => quote = Some(b[j]),
                (Some(q), c) if c == q => quote = None,
                (None, b'>') => break,
                _ => {}
            }
            j += 1;
        }
        if j >= b.len() {
            return None;
        }
        let inner = &text[start + 1..j];
        let closing = inner.starts_with('/');
        let self_closing = inner.ends_with('/');
        let name: String = inner
            .trim_start_matches('/')
            .chars()
            .take_while(|c| !c.is_whitespace() && *c != '/' && *c != '>')
            .collect();
        out.push(Tag {
            name,
            span: start..j + 1,
            closing,
            self_closing,
        });
        i = j + 1;
    }
    Some(out)
}

/// The value of attribute `key` in a start tag, entities decoded.
fn attribute(tag: &str, key: &str) -> Option<String> {
    let mut rest = tag;
    while let Some(pos) = rest.find(key) {
        let before = rest[..pos].chars().last();
        let after = rest[pos + key.len()..].trim_start();
        if before.is_some_and(char::is_whitespace) && after.starts_with('=') {
            let v = after[1..].trim_start();
            let q = v.chars().next()?;
            if q == '"' || q == '\'' {
                let end = v[1..].find(q)?;
                return Some(unescape(&v[1..1 + end]));
            }
        }
        rest = &rest[pos + key.len()..];
    }
    None
}

fn unescape(s: &str) -> String {
    s.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&apos;", "'")
        .replace("&amp;", "&")
}

/// Text escaped for an attribute value in double quotes.
pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joints_in_comments_and_transmissions_are_not_robot_joints() {
        let t = r#"<?xml version="1.0"?><!-- <joint name="ghost"><origin xyz="9 9 9"/></joint> -->
<robot name="r"><link name="a"/><link name="b"/>
<joint name="j&quot;1" type="revolute"><parent link="a"/><child link="b"/>
  <origin xyz="0 0 1" rpy="0 0 0"></origin><axis xyz="0 0 1"/></joint>
<joint name="f" type="fixed"><parent link="b"/><child link="c"/></joint>
<transmission name="t"><joint name="j&quot;1"><origin xyz="1 1 1"/></joint></transmission>
</robot>"#;
        let (js, end) = joints(t).unwrap();
        assert_eq!(js.len(), 2);
        assert_eq!(js[0].name, "j\"1");
        assert_eq!(
            &t[js[0].origin.clone().unwrap()],
            r#"<origin xyz="0 0 1" rpy="0 0 0"></origin>"#
        );
        assert_eq!(js[1].name, "f");
        assert!(js[1].origin.is_none());
        assert!(t[end..].starts_with("</robot>"));
    }
}
