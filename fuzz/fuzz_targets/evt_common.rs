// Shared by the EVT decoder targets: the same bytes decoded in one piece and in pieces of
// fuzzer-chosen sizes into a fuzzer-chosen output size must give the same events and
// statistics, and nothing may panic.

use evcal_core::{
    event::Event,
    evt::{Decoder, Encoding},
};

fn decode(encoding: Encoding, bytes: &[u8], chunk: usize, out_len: usize) -> (Vec<Event>, Decoder) {
    let mut dec = Decoder::new(encoding);
    let mut out = vec![Event::default(); out_len];
    let mut got = Vec::new();
    for piece in bytes.chunks(chunk.max(1)) {
        let mut rest = piece;
        loop {
            let r = dec.decode(rest, &mut out);
            got.extend_from_slice(&out[..r.events]);
            rest = &rest[r.consumed..];
            if rest.is_empty() && r.events < out.len() {
                break;
            }
        }
    }
    (got, dec)
}

pub fn check(encoding: Encoding, data: &[u8]) {
    let Some((&[a, b], bytes)) = data.split_first_chunk::<2>() else { return };
    let (whole, d1) = decode(encoding, bytes, usize::MAX, 4096);
    let (pieces, d2) = decode(encoding, bytes, usize::from(a % 17) + 1, usize::from(b % 40) + 1);
    assert_eq!(whole, pieces);
    assert_eq!(d1.stats(), d2.stats());
    assert_eq!(d2.stats().bytes, bytes.len() as u64);
    assert_eq!(d2.pending_bytes(), bytes.len() % encoding.word_bytes());
    assert_eq!(d2.stats().events, whole.len() as u64);
}
