//! Size and nesting limits on text handed to the XML (URDF, SRDF) and YAML (MoveIt scenes and requests,
//! fabric configurations) parsers.
//!
//! The parsers recurse once per nesting level: a file nested some 20,000 elements deep overflows the stack
//! (the process dies, whatever catches errors above), and YAML nested 100,000 levels takes about a minute
//! before the parser refuses it. Each check here is one linear pass over the text, run before any parser
//! sees it, and returns a message saying which limit the text exceeds and where.
//!
//! The limits sit far above real files: the MotionBenchMaker Panda, UR5 and Fetch URDFs are 5 elements
//! deep at most and their SRDFs 3, URDFs and SRDFs are kilobytes to a few megabytes, and MoveIt scenes and
//! requests are indented by at most 10 columns. Meshes inside a MoveIt scene make the largest YAML files.

/// Largest XML text (URDF or SRDF) accepted, bytes (32 MiB).
pub const XML_MAX_BYTES: usize = 32 << 20;
/// Deepest element nesting accepted in an XML text (the root element is depth 1).
pub const XML_MAX_DEPTH: usize = 64;
/// Largest YAML text accepted, bytes (64 MiB).
pub const YAML_MAX_BYTES: usize = 64 << 20;
/// Deepest YAML nesting accepted, as bounded by [`yaml_depth_bound`].
pub const YAML_MAX_DEPTH: usize = 64;

/// `Err(message)` when `text` exceeds [`XML_MAX_BYTES`] or nests elements deeper than [`XML_MAX_DEPTH`],
/// or declares entities (`<!ENTITY`), which could expand to any depth or size after this scan.
pub fn check_xml(text: &str) -> Result<(), String> {
    if text.len() > XML_MAX_BYTES {
        return Err(format!(
            "{} bytes exceed the limit of {XML_MAX_BYTES} bytes for an XML file",
            text.len()
        ));
    }
    let (depth, line) = xml_depth(text).map(|s| (s.max, s.max_line))?;
    if depth > XML_MAX_DEPTH {
        return Err(format!(
            "elements nested more than {XML_MAX_DEPTH} deep (line {line}); real robot descriptions nest \
             fewer than 10"
        ));
    }
    Ok(())
}

/// For a text the XML parser refused: a sentence saying that it ends inside an element (naming the
/// innermost open element and its line), or inside a comment or tag, when it does; the usual sign of a
/// truncated file, which parsers report in terms of what they expected next.
pub fn xml_truncation(text: &str) -> Option<String> {
    let scan = xml_depth(text).ok()?;
    if scan.max > XML_MAX_DEPTH {
        return None;
    }
    if scan.unterminated {
        return Some(format!(
            "the text ends inside a tag, comment or declaration (line {}): the file looks truncated",
            scan.lines
        ));
    }
    let (name, line) = scan.open.last()?;
    Some(format!(
        "the text ends before <{name}> (line {line}) is closed: the file looks truncated"
    ))
}

/// What [`xml_depth`] finds.
struct XmlScan {
    /// Deepest nesting (stops counting once past [`XML_MAX_DEPTH`]) and the line where it is reached.
    max: usize,
    max_line: usize,
    /// Elements open at the end of the text: name and line of the start tag, outermost first.
    open: Vec<(String, usize)>,
    /// The text ends inside a tag, comment, CDATA section or declaration.
    unterminated: bool,
    /// Number of lines.
    lines: usize,
}

/// The deepest element nesting of `text` and the line (1-based) where it is first reached; stops counting
/// once past [`XML_MAX_DEPTH`]. Tags are counted outside comments, CDATA sections, processing
/// instructions and quoted attribute values; a self-closing tag (`<a/>`) opens nothing. Malformed XML
/// gives some depth and is left to the parser to reject. `Err` for an entity declaration.
fn xml_depth(text: &str) -> Result<XmlScan, String> {
    let b = text.as_bytes();
    let (mut i, mut max, mut line, mut max_line) = (0usize, 0usize, 1usize, 1usize);
    let mut open: Vec<(String, usize)> = Vec::new();
    let mut unterminated = false;
    // skip to just past `end`, counting lines; the end of the text (and `unterminated`) when absent
    let skip = |i: usize, end: &[u8], line: &mut usize, unterminated: &mut bool| -> usize {
        let mut k = i;
        while k < b.len() {
            if b[k..].starts_with(end) {
                return k + end.len();
            }
            if b[k] == b'\n' {
                *line += 1;
            }
            k += 1;
        }
        *unterminated = true;
        b.len()
    };
    while i < b.len() {
        match b[i] {
            b'\n' => {
                line += 1;
                i += 1;
            }
            b'<' => {
                let rest = &b[i..];
                if rest.starts_with(b"<!--") {
                    i = skip(i + 4, b"-->", &mut line, &mut unterminated);
                } else if rest.starts_with(b"<![CDATA[") {
                    i = skip(i + 9, b"]]>", &mut line, &mut unterminated);
                } else if rest.starts_with(b"<?") {
                    i = skip(i + 2, b"?>", &mut line, &mut unterminated);
                } else if rest.starts_with(b"<!") {
                    // DOCTYPE and other declarations: entities are refused, the rest skipped
                    let end = skip(i + 2, b">", &mut line, &mut unterminated);
                    let decl = &b[i..end];
                    let doctype = rest.len() >= 9 && rest[..9].eq_ignore_ascii_case(b"<!DOCTYPE");
                    if decl.windows(8).any(|w| w.eq_ignore_ascii_case(b"<!ENTITY"))
                        || doctype && decl.contains(&b'[')
                    {
                        return Err(format!(
                            "line {line}: document type declarations with entities or an internal \
                             subset are not accepted"
                        ));
                    }
                    i = end;
                } else if rest.starts_with(b"</") {
                    open.pop();
                    i = skip(i + 2, b">", &mut line, &mut unterminated);
                } else {
                    // a start tag: scan to its '>' outside quoted attribute values
                    let start_line = line;
                    let mut k = i + 1;
                    let mut quote = None;
                    while k < b.len() {
                        let c = b[k];
                        if c == b'\n' {
                            line += 1;
                        }
                        match quote {
                            Some(q) if c == q => quote = None,
                            Some(_) => {}
                            None if c == b'"' || c == b'\'' => quote = Some(c),
                            None if c == b'>' => break,
                            None => {}
                        }
                        k += 1;
                    }
                    unterminated |= k >= b.len();
                    let self_closing = k < b.len() && k > i + 1 && b[k - 1] == b'/';
                    if !self_closing {
                        let name_end = (i + 1..k.min(b.len()))
                            .find(|&e| b[e].is_ascii_whitespace() || b[e] == b'/' || b[e] == b'>')
                            .unwrap_or(k.min(b.len()));
                        open.push((
                            String::from_utf8_lossy(&b[i + 1..name_end]).into_owned(),
                            start_line,
                        ));
                        if open.len() > max {
                            max = open.len();
                            max_line = start_line;
                            if max > XML_MAX_DEPTH {
                                break;
                            }
                        }
                    }
                    i = k + 1;
                }
            }
            _ => i += 1,
        }
    }
    Ok(XmlScan {
        max,
        max_line,
        open,
        unterminated,
        lines: line,
    })
}

/// `Err(message)` when `text` exceeds [`YAML_MAX_BYTES`] or may nest deeper than [`YAML_MAX_DEPTH`]
/// (see [`yaml_depth_bound`]).
pub fn check_yaml(text: &str) -> Result<(), String> {
    if text.len() > YAML_MAX_BYTES {
        return Err(format!(
            "{} bytes exceed the limit of {YAML_MAX_BYTES} bytes for a YAML file",
            text.len()
        ));
    }
    let (depth, line) = yaml_depth_bound(text);
    if depth > YAML_MAX_DEPTH {
        return Err(format!(
            "nested more than {YAML_MAX_DEPTH} levels deep (line {line}); MoveIt scenes and requests nest \
             fewer than 15"
        ));
    }
    Ok(())
}

/// An upper bound on the nesting depth of the YAML `text`, and the line (1-based) where it is reached.
///
/// Per line, outside comments and quoted scalars: a block collection one level deeper than its parent
/// is indented at least one column further, except a sequence inside a mapping, which may share its
/// key's column; so the leading spaces `n` allow at most 2·(n + 1) block levels. Each compact `- `
/// or `? ` entry marker on the line adds one or two levels more, and each open `[` or `{` (which may span
/// lines) one. The bound is exact for flow collections and generous for block ones, which is all a limit
/// needs. Stops once past [`YAML_MAX_DEPTH`].
pub fn yaml_depth_bound(text: &str) -> (usize, usize) {
    let (mut flow, mut max, mut max_line) = (0usize, 0usize, 1usize);
    let mut quote: Option<u8> = None;
    for (index, raw) in text.split('\n').enumerate() {
        let b = raw.as_bytes();
        let mut k = 0;
        let mut block = 0;
        if quote.is_none() && flow == 0 {
            while k < b.len() && b[k] == b' ' {
                k += 1;
            }
            block = 2 * (k + 1);
            // compact nested entries: `- - - x`, `? - x`
            while k + 1 < b.len() && (b[k] == b'-' || b[k] == b'?') && b[k + 1] == b' ' {
                block += 2;
                k += 2;
                while k < b.len() && b[k] == b' ' {
                    k += 1;
                }
            }
        }
        let mut deepest = block + flow;
        let mut prev = b' ';
        while k < b.len() {
            let c = b[k];
            match quote {
                Some(b'\'') if c == b'\'' => quote = None,
                Some(b'"') if c == b'\\' => k += 1,
                Some(b'"') if c == b'"' => quote = None,
                Some(_) => {}
                None => match c {
                    b'#' if prev == b' ' || prev == b'\t' => break,
                    b'\'' | b'"' => quote = Some(c),
                    b'[' | b'{' => {
                        flow += 1;
                        deepest = deepest.max(block + flow);
                    }
                    b']' | b'}' => flow = flow.saturating_sub(1),
                    _ => {}
                },
            }
            prev = c;
            k += 1;
        }
        if deepest > max {
            max = deepest;
            max_line = index + 1;
            if max > YAML_MAX_DEPTH {
                break;
            }
        }
    }
    (max, max_line)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xml_depth_counts_elements_not_comments_or_attributes() {
        let xml = "<?xml version='1.0'?>\n<!-- <a><a><a> -->\n<robot name='r>'>\n  <link name='a'><visual/>\
                   </link>\n  <![CDATA[<x><y>]]>\n</robot>";
        let scan = xml_depth(xml).unwrap();
        assert_eq!((scan.max, scan.max_line, scan.open.len()), (2, 4, 0));
        assert_eq!(
            xml_truncation("<robot name='r'>\n  <link name='a'>\n").as_deref(),
            Some("the text ends before <link> (line 2) is closed: the file looks truncated")
        );
        assert!(xml_truncation("<robot><link name='a")
            .unwrap()
            .contains("inside a tag"));
        let deep = format!("<r>{}{}</r>", "<a>".repeat(70), "</a>".repeat(70));
        assert!(check_xml(&deep).unwrap_err().contains("more than 64 deep"));
        assert!(check_xml("<!DOCTYPE r [<!ENTITY a 'x'>]><r>&a;</r>").is_err());
    }

    #[test]
    fn yaml_bound_covers_block_and_flow_nesting() {
        let (d, _) = yaml_depth_bound("a:\n  b:\n    c: [1, {x: 2}]\n");
        assert!((4..=14).contains(&d), "{d}");
        let deep = format!("{}1{}", "[".repeat(100), "]".repeat(100));
        assert!(check_yaml(&deep)
            .unwrap_err()
            .contains("more than 64 levels"));
        // brackets inside quotes and comments open nothing
        let (d, _) = yaml_depth_bound(
            "a: '[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[['  # [[[[\n",
        );
        assert!(d <= 4, "{d}");
    }
}
