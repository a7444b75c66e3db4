//! The pieces rt's saved structures share: the little-endian [`Writer`] and [`Reader`],
//! [`LoadError`], the hash of the triangles a structure was built over, and the check that
//! a triangle is covered by boxes or cells (the leaves a structure lists it in), in `f64`.

use crate::{Aabb, Triangle};
use std::fmt;

/// Why saved bytes were refused.
#[derive(Clone, Debug, PartialEq)]
pub enum LoadError {
    /// Not an rt structure (the magic bytes differ).
    NotASavedStructure,
    /// Saved by another version of the format.
    Version {
        /// The version found.
        found: u32,
    },
    /// A structure of another kind (leaves, width or node layout) than the one asked to load.
    Layout {
        /// Family (0: triangles, 1: any primitives), lanes and node kind found.
        found: (u8, u8, u8),
        /// Family, lanes and node kind asked for.
        expected: (u8, u8, u8),
    },
    /// The bytes end before the structure does.
    Truncated,
    /// Bytes left after the structure.
    TrailingBytes,
    /// The primitives given are not the ones the structure was built over.
    OtherPrimitives,
    /// A field holds a value no build writes, or the structure fails its checks.
    Corrupt(String),
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotASavedStructure => write!(f, "not a saved rt structure"),
            Self::Version { found } => {
                write!(f, "saved by another version of the format ({found})")
            }
            Self::Layout { found, expected } => write!(
                f,
                "a structure of family {}, {}-wide, node kind {}: not family {}, {}-wide, kind {}",
                found.0, found.1, found.2, expected.0, expected.1, expected.2
            ),
            Self::Truncated => write!(f, "the bytes end before the structure does"),
            Self::TrailingBytes => write!(f, "bytes left after the structure"),
            Self::OtherPrimitives => {
                write!(
                    f,
                    "the primitives are not the ones the structure was built over"
                )
            }
            Self::Corrupt(why) => write!(f, "corrupt structure: {why}"),
        }
    }
}

impl std::error::Error for LoadError {}

/// Saved contents a build would refuse (for loaders that run a build's own checks).
impl From<crate::BuildError> for LoadError {
    fn from(e: crate::BuildError) -> Self {
        Self::Corrupt(e.to_string())
    }
}

/// Little-endian writer of a saved structure.
#[derive(Default)]
pub struct Writer(pub Vec<u8>);

impl Writer {
    /// Appends a byte.
    pub fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    /// Appends a `u32`.
    pub fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends a `u64`.
    pub fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends an `f32`'s bits.
    pub fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }
    /// Starts a saved structure: its magic bytes and format version.
    pub fn header(&mut self, magic: &[u8; 8], version: u32) {
        self.0.extend_from_slice(magic);
        self.u32(version);
    }
    /// Appends the count of the primitives a structure was built over and their hash.
    pub fn primitives(&mut self, (count, hash): (usize, u64)) {
        self.u64(count as u64);
        self.u64(hash);
    }
}

/// Little-endian reader over the bytes left of a saved structure; every read checks the
/// length.
pub struct Reader<'a>(pub &'a [u8]);

impl Reader<'_> {
    /// The next `K` bytes.
    pub fn take<const K: usize>(&mut self) -> Result<[u8; K], LoadError> {
        let (head, rest) = self
            .0
            .split_first_chunk::<K>()
            .ok_or(LoadError::Truncated)?;
        self.0 = rest;
        Ok(*head)
    }
    /// The next byte.
    pub fn u8(&mut self) -> Result<u8, LoadError> {
        Ok(self.take::<1>()?[0])
    }
    /// The next `u32`.
    pub fn u32(&mut self) -> Result<u32, LoadError> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    /// The next `u64`.
    pub fn u64(&mut self) -> Result<u64, LoadError> {
        Ok(u64::from_le_bytes(self.take()?))
    }
    /// The next `f32`.
    pub fn f32(&mut self) -> Result<f32, LoadError> {
        Ok(f32::from_bits(self.u32()?))
    }
    /// Checks what [`Writer::header`] wrote: `magic` (else not a saved structure of this
    /// kind) and `version`.
    pub fn header(&mut self, magic: &[u8; 8], version: u32) -> Result<(), LoadError> {
        if self.take::<8>().ok().as_ref() != Some(magic) {
            return Err(LoadError::NotASavedStructure);
        }
        match self.u32()? {
            found if found == version => Ok(()),
            found => Err(LoadError::Version { found }),
        }
    }
    /// Checks what [`Writer::primitives`] wrote against the primitives given.
    pub fn primitives(&mut self, (count, hash): (usize, u64)) -> Result<(), LoadError> {
        if (self.u64()?, self.u64()?) != (count as u64, hash) {
            return Err(LoadError::OtherPrimitives);
        }
        Ok(())
    }
    /// A count of items of `size` bytes each, no more than the bytes left hold.
    pub fn count(&mut self, size: usize) -> Result<usize, LoadError> {
        let n = self.u64()?;
        if n > (self.0.len() / size.max(1)) as u64 {
            return Err(LoadError::Truncated);
        }
        Ok(n as usize)
    }
}

/// The triangle as a polygon in `f64`, and its size (its largest coordinate magnitude plus
/// its longest edge from the first vertex), the scale [`thick`] measures against.
pub fn polygon(t: &Triangle) -> (Vec<crate::DVec3>, f64) {
    let tri: Vec<crate::DVec3> = t.v.iter().map(|v| v.as_dvec3()).collect();
    let size = tri
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0.0, f64::max)
        + (tri[1] - tri[0]).length().max((tri[2] - tri[0]).length());
    (tri, size)
}

/// Whether `boxes` cover the triangle: removing each box from it (clipping the rest to the
/// six outer half-spaces, in `f64`) leaves nothing thicker than `1e-9` of the triangle's size,
/// far below the `f32` resolution the box tests' padding covers.
pub fn covered(t: &Triangle, boxes: &[Aabb]) -> bool {
    let (tri, size) = polygon(t);
    let mut left = vec![tri];
    for b in boxes {
        let mut rest = Vec::new();
        for piece in left {
            // The parts of `piece` beyond each face of `b`, in turn; what is within all six
            // is removed.
            let mut within = piece;
            for (axis, bound, below) in
                (0..3).flat_map(|a| [(a, b.min[a] as f64, true), (a, b.max[a] as f64, false)])
            {
                let (out, inn) = split_polygon(&within, axis, bound, below);
                if thick(&out, size) {
                    rest.push(out);
                }
                within = inn;
                if within.len() < 3 {
                    break;
                }
            }
        }
        left = rest;
        if left.is_empty() {
            return true;
        }
    }
    left.is_empty()
}

/// The parts of convex polygon `p` beyond the plane `x[axis] = bound` (below it when
/// `below`) and on the box's side of it.
pub fn split_polygon(
    p: &[crate::DVec3],
    axis: usize,
    bound: f64,
    below: bool,
) -> (Vec<crate::DVec3>, Vec<crate::DVec3>) {
    let side = |q: &crate::DVec3| {
        if below {
            bound - q[axis]
        } else {
            q[axis] - bound
        }
    };
    let (mut out, mut inn) = (Vec::new(), Vec::new());
    for i in 0..p.len() {
        let (a, b) = (p[i], p[(i + 1) % p.len()]);
        let (sa, sb) = (side(&a), side(&b));
        if sa > 0.0 {
            out.push(a);
        } else {
            inn.push(a);
        }
        if (sa > 0.0) != (sb > 0.0) {
            let mut x = a + (b - a) * (sa / (sa - sb));
            x[axis] = bound;
            out.push(x);
            inn.push(x);
        }
    }
    (out, inn)
}

/// Whether polygon `p` is more than a sliver: thicker than `1e-9 * size` (a convex polygon's
/// thickness is at most twice its area over its diameter).
pub fn thick(p: &[crate::DVec3], size: f64) -> bool {
    if p.len() < 3 {
        return false;
    }
    let mut area2 = crate::DVec3::ZERO;
    for i in 1..p.len() - 1 {
        area2 += (p[i] - p[0]).cross(p[i + 1] - p[0]);
    }
    let diameter = p
        .iter()
        .flat_map(|a| p.iter().map(move |b| (*a - *b).length()))
        .fold(0.0, f64::max);
    diameter > 0.0 && area2.length() / diameter > 1e-9 * size
}

/// A 64-bit FNV-1a hash taken over 32-bit words (not bytes): the triangle count, then every
/// vertex coordinate's bits.
pub fn triangle_hash(tris: &[Triangle]) -> u64 {
    let coordinates = tris.iter().flat_map(|t| t.v).flat_map(|v| v.to_array());
    words_hash(std::iter::once(tris.len() as u32).chain(coordinates.map(f32::to_bits)))
}

/// The 64-bit FNV-1a hash of `words`, taken word by word.
pub fn words_hash(words: impl IntoIterator<Item = u32>) -> u64 {
    let eat = |h: u64, w: u32| (h ^ w as u64).wrapping_mul(0x0100_0000_01b3);
    words.into_iter().fold(0xcbf2_9ce4_8422_2325, eat)
}
