//! What the readers of model descriptions and SSDs share: the element tags of an XML text,
//! in document order, with everything else (text, comments, declarations) passed over. Public
//! for the packager, which reads the FMI 3.0 description it writes beside the terminals and
//! reference results of an archive.

use quick_xml::events::{BytesEnd, BytesStart, Event};
use quick_xml::Reader;

/// An element's start tag (`empty`: a self-closing `<a/>`), or an end tag.
pub enum Tag {
    Start {
        element: BytesStart<'static>,
        empty: bool,
    },
    End(BytesEnd<'static>),
}

/// The tags of `text`; the first malformed one ends the walk with its error, which names the
/// line. Besides what the reader checks (an end tag matches its start tag), the walk checks
/// what makes the whole text a well-formed document: one root element, every element
/// closed before the end, no element after the root.
pub fn tags(text: &str) -> Tags<'_> {
    Tags {
        reader: Reader::from_str(text),
        text,
        open: Vec::new(),
        root_closed: false,
        failed: false,
    }
}

pub struct Tags<'a> {
    reader: Reader<&'a [u8]>,
    text: &'a str,
    /// The names of the elements open at the reader's position, outermost first.
    open: Vec<String>,
    /// Whether the root element has been closed (no element may follow it).
    root_closed: bool,
    /// Whether an error has been returned (the walk ends after it).
    failed: bool,
}

impl Tags<'_> {
    /// The 1-based line of the byte at `position`.
    fn line(&self, position: u64) -> usize {
        let end = usize::try_from(position)
            .unwrap_or(usize::MAX)
            .min(self.text.len());
        1 + self.text.as_bytes()[..end]
            .iter()
            .filter(|b| **b == b'\n')
            .count()
    }

    fn fail(&mut self, position: u64, reason: String) -> Option<Result<Tag, String>> {
        self.failed = true;
        Some(Err(format!(
            "ill-formed XML at line {}: {reason}",
            self.line(position)
        )))
    }
}

impl Iterator for Tags<'_> {
    type Item = Result<Tag, String>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        loop {
            let before = self.reader.buffer_position();
            let tag = match self.reader.read_event() {
                Err(e) => {
                    let at = self.reader.error_position();
                    return self.fail(at, e.to_string());
                }
                Ok(Event::Start(e)) => Tag::Start {
                    element: e.into_owned(),
                    empty: false,
                },
                Ok(Event::Empty(e)) => Tag::Start {
                    element: e.into_owned(),
                    empty: true,
                },
                Ok(Event::End(e)) => Tag::End(e.into_owned()),
                Ok(Event::Eof) => {
                    return match self.open.last() {
                        Some(name) => {
                            let reason = format!(
                                "the text ends with <{name}> still open ({} element(s) unclosed)",
                                self.open.len()
                            );
                            let end = self.text.len() as u64;
                            self.fail(end, reason)
                        }
                        None if !self.root_closed => {
                            let end = self.text.len() as u64;
                            self.fail(end, "no root element".to_string())
                        }
                        None => None,
                    };
                }
                Ok(_) => continue,
            };
            match &tag {
                Tag::Start { element, empty } => {
                    if self.root_closed && self.open.is_empty() {
                        let reason = format!(
                            "<{}> after the root element has ended",
                            element.name().as_ref()
                        );
                        return self.fail(before, reason);
                    }
                    if *empty {
                        self.root_closed |= self.open.is_empty();
                    } else {
                        self.open.push(element.name().as_ref().to_string());
                    }
                }
                Tag::End(_) => {
                    // The reader has checked that the name matches the open element.
                    self.open.pop();
                    self.root_closed |= self.open.is_empty();
                }
            }
            return Some(Ok(tag));
        }
    }
}

/// The value of the attribute `key` of `element` (entities resolved, white space as XML 1.0
/// normalises it); `None` when it is absent or malformed.
pub fn attribute(element: &BytesStart, key: &str) -> Option<String> {
    element
        .attributes()
        .flatten()
        .find(|a| a.key.as_ref() == key)
        .and_then(|a| {
            a.normalized_value(quick_xml::XmlVersion::Implicit1_0)
                .ok()
                .map(|v| v.to_string())
        })
}
