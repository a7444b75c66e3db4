//! Ray and hit files, for exchanging rays and answers with other engines: the one module that
//! reads and writes them.
//!
//! `.rays`: little-endian `f32`, 8 per ray: `ox oy oz tmin dx dy dz tmax` (`tmax` may be +inf).
//! `.hits`: per ray, little-endian `f32 t` (+inf on a miss) then `u32 prim` (`0xFFFFFFFF` on a
//! miss).

use rt_geom::{Hit, Ray, Vec3};
use std::io::Write;
use std::path::Path;

/// Bytes per ray in a `.rays` file: little-endian `f32`, `ox oy oz tmin dx dy dz tmax`.
pub const RAY_BYTES: usize = 32;
/// Bytes per hit in a `.hits` file: little-endian `f32 t`, `u32 prim`.
pub const HIT_BYTES: usize = 8;
/// The `prim` of a miss.
pub const MISS_PRIM: u32 = u32::MAX;

/// Reads a ray file. A size that is not a multiple of 32 bytes is an error naming the file.
pub fn read_rays(path: &Path) -> Result<Vec<Ray>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    parse_rays(&bytes).map_err(|e| format!("{}: {e}", path.display()))
}

/// The rays of a `.rays` file's bytes; a size that is not a multiple of [`RAY_BYTES`] is an
/// error.
pub fn parse_rays(bytes: &[u8]) -> Result<Vec<Ray>, String> {
    if bytes.len() % RAY_BYTES != 0 {
        return Err(format!(
            "size {} is not a multiple of {RAY_BYTES} bytes (8 f32 per ray): truncated or not a ray file",
            bytes.len()
        ));
    }
    Ok(bytes
        .chunks_exact(RAY_BYTES)
        .map(|c| {
            let f = |i: usize| f32::from_le_bytes(c[4 * i..4 * i + 4].try_into().unwrap());
            Ray::segment(
                Vec3::new(f(0), f(1), f(2)),
                Vec3::new(f(4), f(5), f(6)),
                f(3),
                f(7),
            )
        })
        .collect())
}

/// The bytes of a `.rays` file.
pub fn encode_rays(rays: &[Ray]) -> Vec<u8> {
    let mut out = Vec::with_capacity(rays.len() * RAY_BYTES);
    for r in rays {
        let (o, d) = (r.origin(), r.dir());
        for x in [o.x, o.y, o.z, r.tmin, d.x, d.y, d.z, r.tmax] {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    out
}

/// Writes a `.rays` file.
pub fn write_rays(path: &Path, rays: &[Ray]) -> Result<(), String> {
    write_file(path, &encode_rays(rays))
}

/// One record of a hit file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitRecord {
    /// The hit's `t` (+inf on a miss).
    pub t: f32,
    /// The primitive hit ([`MISS_PRIM`] on a miss).
    pub prim: u32,
}

impl HitRecord {
    /// A miss.
    pub const MISS: HitRecord = HitRecord {
        t: f32::INFINITY,
        prim: MISS_PRIM,
    };

    /// The record of a closest-hit answer.
    pub fn from_hit(h: Option<Hit>) -> Self {
        h.map_or(Self::MISS, |h| HitRecord {
            t: h.t,
            prim: h.prim,
        })
    }

    /// What `trace --occluded` writes: an occluded ray is `t = 0, prim = 0`.
    pub fn from_occluded(occluded: bool) -> Self {
        if occluded {
            HitRecord { t: 0.0, prim: 0 }
        } else {
            Self::MISS
        }
    }

    /// Whether the record is a hit.
    pub fn is_hit(&self) -> bool {
        self.prim != MISS_PRIM
    }
}

/// The bytes of a `.hits` file.
pub fn encode_hits(hits: &[HitRecord]) -> Vec<u8> {
    let mut out = Vec::with_capacity(hits.len() * HIT_BYTES);
    for h in hits {
        out.extend_from_slice(&h.t.to_le_bytes());
        out.extend_from_slice(&h.prim.to_le_bytes());
    }
    out
}

/// The records of a `.hits` file's bytes.
pub fn parse_hits(bytes: &[u8]) -> Result<Vec<HitRecord>, String> {
    if bytes.len() % HIT_BYTES != 0 {
        return Err(format!(
            "size {} is not a multiple of {HIT_BYTES} bytes",
            bytes.len()
        ));
    }
    Ok(bytes
        .chunks_exact(HIT_BYTES)
        .map(|c| HitRecord {
            t: f32::from_le_bytes(c[0..4].try_into().unwrap()),
            prim: u32::from_le_bytes(c[4..8].try_into().unwrap()),
        })
        .collect())
}

/// Writes a `.hits` file.
pub fn write_hits(path: &Path, hits: &[HitRecord]) -> Result<(), String> {
    write_file(path, &encode_hits(hits))
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let mut f = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
    f.write_all(bytes)
        .map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rt_geom::Vec3;

    #[test]
    fn round_trip_and_truncation() {
        let rays = vec![
            Ray::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, -1.0, 0.5)),
            Ray::segment(Vec3::ZERO, Vec3::X, 0.25, 7.0),
        ];
        let bytes = encode_rays(&rays);
        assert_eq!(bytes.len(), 64);
        let back = parse_rays(&bytes).unwrap();
        assert_eq!(back, rays);
        assert!(back[0].tmax.is_infinite());
        let e = parse_rays(&bytes[..60]).unwrap_err();
        assert!(e.contains("not a multiple of 32"), "{e}");
        let hits = [HitRecord { t: 1.5, prim: 7 }, HitRecord::MISS];
        assert_eq!(parse_hits(&encode_hits(&hits)).unwrap(), hits);
        assert!(
            read_rays(Path::new("/no/such/file.rays"))
                .unwrap_err()
                .contains("/no/such")
        );
    }
}
