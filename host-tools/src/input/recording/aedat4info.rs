//! The info node of an AEDAT4 file (the XML document its IOHeader holds): the streams it
//! lists, and the choice of the event stream to read.

use evcal_core::event::SensorSize;

/// One stream listed in the info node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StreamInfo {
    /// The id packets carry.
    pub id: i32,
    /// The output's name (`originalOutputName`, e.g. `events`, `frames`).
    pub name: String,
    /// The type identifier (`EVTS` events, `FRME` frames, `IMUS`, `TRIG`, ...).
    pub type_id: String,
    /// The sensor size, for streams that state one (`sizeX`, `sizeY`).
    pub size: Option<SensorSize>,
}

impl std::fmt::Display for StreamInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} '{}' ({})", self.id, self.name, self.type_id)
    }
}

/// The streams of an info node: `<node name="outInfo">` holds one `<node name="ID">` per
/// stream with `<attr key="typeIdentifier">`, `<attr key="originalOutputName">` and a child
/// `<node name="info">` with `sizeX` / `sizeY`. Besides, the streams whose stated size evcal
/// cannot use (not whole numbers, or outside 1 to 65535), each with what it states.
#[allow(clippy::type_complexity)]
pub(super) fn parse_info(xml: &str) -> Result<(Vec<StreamInfo>, Vec<(i32, String)>), String> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("the info node is not valid XML: {e}"))?;
    let out_info = doc
        .descendants()
        .find(|n| n.has_tag_name("node") && n.attribute("name") == Some("outInfo"))
        .ok_or("the info node has no 'outInfo' node listing the streams")?;
    let attr = |node: roxmltree::Node<'_, '_>, key: &str| -> Option<String> {
        node.children()
            .find(|c| c.has_tag_name("attr") && c.attribute("key") == Some(key))
            .map(|c| c.text().unwrap_or("").trim().to_string())
    };
    let mut streams = Vec::new();
    let mut bad_sizes = Vec::new();
    for node in out_info.children().filter(|c| c.has_tag_name("node")) {
        let Some(id) = node.attribute("name").and_then(|n| n.parse::<i32>().ok()) else { continue };
        let info = node.children().find(|c| c.has_tag_name("node") && c.attribute("name") == Some("info"));
        let stated = info.and_then(|i| Some((attr(i, "sizeX")?, attr(i, "sizeY")?)));
        let size = match stated {
            None => None,
            Some((w, h)) => match (w.parse::<i128>(), h.parse::<i128>()) {
                (Ok(w), Ok(h)) => super::types::stated_sensor(w, h).unwrap_or_else(|m| {
                    bad_sizes.push((id, m));
                    None
                }),
                _ => {
                    let q = |v: &str| super::bytes::quote(v.as_bytes(), 40);
                    bad_sizes.push((
                        id,
                        format!("states a sensor size of \"{}\" by \"{}\", not whole numbers", q(&w), q(&h)),
                    ));
                    None
                }
            },
        };
        streams.push(StreamInfo {
            id,
            name: attr(node, "originalOutputName").unwrap_or_default(),
            type_id: attr(node, "typeIdentifier").unwrap_or_default(),
            size,
        });
    }
    Ok((streams, bad_sizes))
}

/// The event stream to read: `wanted` by name or id, else the only one, else `events`.
pub(super) fn choose_stream(streams: &[StreamInfo], wanted: Option<&str>) -> Result<StreamInfo, String> {
    let list = || streams.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", ");
    if let Some(w) = wanted {
        let s = streams
            .iter()
            .find(|s| s.name == w || w.parse::<i32>().is_ok_and(|id| id == s.id))
            .ok_or_else(|| format!("no stream '{w}' in this AEDAT4 file; its streams: {}", list()))?;
        if s.type_id != "EVTS" {
            return Err(format!("stream {s} holds no events (type EVTS); the file's streams: {}", list()));
        }
        return Ok(s.clone());
    }
    let events: Vec<&StreamInfo> = streams.iter().filter(|s| s.type_id == "EVTS").collect();
    match events.as_slice() {
        [one] => Ok((*one).clone()),
        [] => Err(format!("no event stream (type EVTS) in this AEDAT4 file; its streams: [{}]", list())),
        many => {
            let named: Vec<_> = many.iter().filter(|s| s.name == "events").collect();
            if let [one] = named.as_slice() {
                Ok((**one).clone())
            } else {
                Err(format!(
                    "several event streams: choose one with --topic NAME or ID; the file's streams: {}",
                    list()
                ))
            }
        }
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use evcal_core::event::SensorSize;

    const INFO: &str = r#"<dv version="2.0"><node name="outInfo" path="/outInfo/">
        <node name="0" path="/outInfo/0/"><attr key="originalOutputName" type="string">events</attr>
          <attr key="typeIdentifier" type="string">EVTS</attr>
          <node name="info" path="/outInfo/0/info/"><attr key="sizeX" type="int">346</attr><attr key="sizeY" type="int">260</attr></node></node>
        <node name="1" path="/outInfo/1/"><attr key="originalOutputName" type="string">frames</attr>
          <attr key="typeIdentifier" type="string">FRME</attr></node>
        <node name="2" path="/outInfo/2/"><attr key="originalOutputName" type="string">right</attr>
          <attr key="typeIdentifier" type="string">EVTS</attr></node>
        </node></dv>"#;

    #[test]
    fn info_node_streams_and_choice() {
        let s = parse_info(INFO).unwrap().0;
        assert_eq!(s.len(), 3);
        assert_eq!(s[0].size, Some(SensorSize::DAVIS346));
        assert_eq!((s[1].name.as_str(), s[1].type_id.as_str(), s[1].size), ("frames", "FRME", None));
        assert_eq!(choose_stream(&s, None).unwrap().id, 0, "two event streams: the one named 'events'");
        assert_eq!(choose_stream(&s, Some("right")).unwrap().id, 2);
        assert_eq!(choose_stream(&s, Some("2")).unwrap().id, 2);
        let e = choose_stream(&s, Some("frames")).unwrap_err();
        assert!(e.contains("holds no events") && e.contains("0 'events' (EVTS)"), "{e}");
        let e = choose_stream(&s, Some("left")).unwrap_err();
        assert!(e.contains("no stream 'left'") && e.contains("2 'right' (EVTS)"), "{e}");
        assert_eq!(choose_stream(&s[1..], None).unwrap().id, 2, "the only event stream, whatever its name");
        let mut two = s.clone();
        two[0].name = "left".into();
        let e = choose_stream(&two, None).unwrap_err();
        assert!(e.contains("several event streams") && e.contains("--topic"), "{e}");
        assert!(choose_stream(&s[1..2], None).unwrap_err().contains("no event stream"));
        let bad = INFO.replace(">346<", ">70000<").replace(">260<", ">2.5<");
        assert!(parse_info(&bad).unwrap().1[0].1.contains("\"70000\" by \"2.5\", not whole numbers"));
        let bad = INFO.replace(">346<", ">70000<");
        let (s, bad) = parse_info(&bad).unwrap();
        assert_eq!(s[0].size, None);
        assert_eq!(bad[0].0, 0);
        assert!(bad[0].1.contains("70000x260; evcal reads sizes of 1 to 65535"), "{bad:?}");
        assert!(parse_info("<dv><node name='x'/></dv>").unwrap_err().contains("outInfo"));
        assert!(parse_info("<dv").unwrap_err().contains("XML"));
    }
}
