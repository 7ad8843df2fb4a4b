//! What the readers of model descriptions and SSDs share: the element tags of an XML text,
//! in document order, with everything else (text, comments, declarations) passed over.

use quick_xml::events::{BytesEnd, BytesStart, Event};
use quick_xml::Reader;

/// An element's start tag (`empty`: a self-closing `<a/>`), or an end tag.
pub(crate) enum Tag {
    Start {
        element: BytesStart<'static>,
        empty: bool,
    },
    End(BytesEnd<'static>),
}

/// The tags of `text`; the first malformed one ends the walk with its error.
pub(crate) fn tags(text: &str) -> Tags<'_> {
    Tags(Reader::from_str(text))
}

pub(crate) struct Tags<'a>(Reader<&'a [u8]>);

impl Iterator for Tags<'_> {
    type Item = Result<Tag, String>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            let tag = match self.0.read_event() {
                Err(e) => return Some(Err(e.to_string())),
                Ok(Event::Start(e)) => Tag::Start {
                    element: e.into_owned(),
                    empty: false,
                },
                Ok(Event::Empty(e)) => Tag::Start {
                    element: e.into_owned(),
                    empty: true,
                },
                Ok(Event::End(e)) => Tag::End(e.into_owned()),
                Ok(Event::Eof) => return None,
                Ok(_) => continue,
            };
            return Some(Ok(tag));
        }
    }
}

/// The value of the attribute `key` of `element` (entities resolved, white space as XML 1.0
/// normalises it); `None` when it is absent or malformed.
pub(crate) fn attribute(element: &BytesStart, key: &str) -> Option<String> {
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
