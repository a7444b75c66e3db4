//! Split-plane events (Wald & Havran 2006, section 4): every primitive's box, clipped to the
//! node, contributes per axis a *start* and an *end* event, or one *planar* event when the box
//! is flat along that axis. Each axis keeps its events sorted by `(position, kind)` with
//! `End < Planar < Start`, so one sweep counts the primitives on either side of every
//! candidate plane. The lists are sorted once at the root; a split keeps the order of the
//! primitives that fall on one side and merges in the few re-clipped straddlers.

use rayon::slice::ParallelSliceMut;
use rt_geom::Aabb;

/// Kinds, in the order events at one position are swept.
pub(crate) const END: u32 = 0;
pub(crate) const PLANAR: u32 = 1;
pub(crate) const START: u32 = 2;

/// One event: 8 bytes. `key` holds the primitive's index in its node (`key >> 2`) and the
/// kind (`key & 3`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Event {
    pub pos: f32,
    key: u32,
}

/// Largest number of primitives a node's local index can address.
pub(crate) const MAX_LOCAL: usize = (1 << 30) - 1;

impl Event {
    #[inline]
    pub fn new(pos: f32, local: u32, kind: u32) -> Self {
        // `+ 0.0` turns -0 into +0, so that equal positions sort next to each other.
        Self {
            pos: pos + 0.0,
            key: (local << 2) | kind,
        }
    }

    #[inline]
    pub fn local(&self) -> u32 {
        self.key >> 2
    }

    #[inline]
    pub fn kind(&self) -> u32 {
        self.key & 3
    }

    /// A copy that belongs to primitive `local` of another node.
    #[inline]
    pub fn renumbered(&self, local: u32) -> Self {
        Self {
            pos: self.pos,
            key: (local << 2) | self.kind(),
        }
    }

    /// The sort key: position (as an order-preserving integer), then kind.
    #[inline]
    fn order(&self) -> u64 {
        let bits = self.pos.to_bits();
        let ordered = if bits >> 31 == 1 {
            !bits
        } else {
            bits | 1 << 31
        };
        ((ordered as u64) << 2) | self.kind() as u64
    }
}

/// Events of all three axes of one node.
pub(crate) type AxisEvents = [Vec<Event>; 3];

/// Appends the events of primitive `local` whose clipped box is `b`.
#[inline]
pub(crate) fn push_box(events: &mut AxisEvents, local: u32, b: &Aabb) {
    for (k, list) in events.iter_mut().enumerate() {
        if b.min[k] == b.max[k] {
            list.push(Event::new(b.min[k], local, PLANAR));
        } else {
            list.push(Event::new(b.min[k], local, START));
            list.push(Event::new(b.max[k], local, END));
        }
    }
}

/// Sorts each axis (in parallel for long lists).
pub(crate) fn sort(events: &mut AxisEvents) {
    for list in events.iter_mut() {
        if list.len() > 1 << 16 {
            list.par_sort_unstable_by_key(Event::order);
        } else {
            list.sort_unstable_by_key(Event::order);
        }
    }
}

/// Merges two sorted lists into one sorted list.
pub(crate) fn merge(a: Vec<Event>, b: Vec<Event>) -> Vec<Event> {
    if b.is_empty() {
        return a;
    }
    if a.is_empty() {
        return b;
    }
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if b[j].order() < a[i].order() {
            out.push(b[j]);
            j += 1;
        } else {
            out.push(a[i]);
            i += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::Vec3;

    #[test]
    fn order_is_position_then_kind() {
        let mut ev: AxisEvents = Default::default();
        push_box(
            &mut ev,
            0,
            &Aabb::new(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 3.0)),
        );
        push_box(
            &mut ev,
            1,
            &Aabb::new(Vec3::new(-0.0, -2.0, 1.0), Vec3::new(2.0, 0.0, 2.0)),
        );
        sort(&mut ev);
        let x: Vec<(f32, u32)> = ev[0].iter().map(|e| (e.pos, e.kind())).collect();
        assert_eq!(x, [(-1.0, START), (0.0, START), (1.0, END), (2.0, END)]);
        assert!(ev[0][1].pos.is_sign_positive(), "-0 is stored as +0");
        let y: Vec<(f32, u32, u32)> = ev[1].iter().map(|e| (e.pos, e.kind(), e.local())).collect();
        assert_eq!(y, [(-2.0, START, 1), (0.0, END, 1), (0.0, PLANAR, 0)]);
        let z: Vec<u32> = ev[2].iter().map(|e| e.kind()).collect();
        assert_eq!(z, [START, END, START, END], "end before start at 2");
        let merged = merge(ev[0].clone(), vec![Event::new(0.5, 7, PLANAR)]);
        assert_eq!(merged[2].local(), 7);
        assert_eq!(merged.len(), 5);
    }
}
