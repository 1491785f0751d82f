//! A fit's events in its local frame, converted into the caller's scratch.

use super::frame::Frame;
use crate::window::WindowEvent;

/// A fit's events in its local frame, `[x, y, τ]` as [`Frame::local`] gives them: all of
/// them converted once into the scratch when they fit there, else converted a scratchful at
/// a time on every pass.
pub(super) struct Events<'p, 's> {
    parts: &'p [&'p [WindowEvent]],
    pub(super) n: usize,
    pub(super) scratch: &'s mut [[f32; 3]],
    /// Whether `scratch` holds all `n` events.
    pub(super) held: bool,
}

impl<'p, 's> Events<'p, 's> {
    /// `n` is the events in `parts`; `scratch` is not empty.
    pub(super) fn new(parts: &'p [&'p [WindowEvent]], n: usize, f: &Frame, scratch: &'s mut [[f32; 3]]) -> Self {
        let held = n <= scratch.len();
        let mut events = Self { parts, n, scratch, held };
        if held {
            events.convert(f, &mut (0, 0));
        }
        events
    }

    /// Converts the events from position `at` (part, index in it) on into the scratch, as
    /// many as it holds, and moves `at` past them; returns how many.
    pub(super) fn convert(&mut self, f: &Frame, at: &mut (usize, usize)) -> usize {
        let mut m = 0;
        while m < self.scratch.len() {
            let Some(part) = self.parts.get(at.0) else { break };
            let rest = part.get(at.1..).unwrap_or(&[]);
            let room = self.scratch.get_mut(m..).unwrap_or(&mut []);
            let take = rest.len().min(room.len());
            for (o, e) in room.iter_mut().zip(rest) {
                let (x, y, t) = f.local(e);
                *o = [x, y, t];
            }
            m += take;
            at.1 += take;
            if at.1 >= part.len() {
                *at = (at.0 + 1, 0);
            }
        }
        m
    }
}
