//! Tracing a batch of rays through a structure on a fixed number of threads, timed apart from
//! everything else. `bench` and `trace` both measure with this.

use crate::rayfile::HitRecord;
use rayon::prelude::*;
use rt_geom::{Accel, Ray};
use std::time::{Duration, Instant};

/// Rays per rayon task: large enough to amortise scheduling, small enough to balance 2 cores.
const CHUNK: usize = 1024;

/// The most threads a command starts.
pub const MAX_THREADS: usize = 1024;

/// A rayon pool of exactly `threads` threads (0 = rayon's default), at most [`MAX_THREADS`].
pub fn pool(threads: usize) -> Result<rayon::ThreadPool, String> {
    if threads > MAX_THREADS {
        return Err(format!(
            "threads must lie in 0..={MAX_THREADS} (0: one per core), got {threads}"
        ));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("cannot start {threads} threads: {e}"))
}

/// Traces every ray (`intersect`, or `occluded` for shadow rays) into `out`, each `runs`
/// times in a row (1, or 2 to time a ray's second query); returns the time.
pub fn trace_into(
    accel: &dyn Accel,
    rays: &[Ray],
    occluded: bool,
    runs: usize,
    pool: &rayon::ThreadPool,
    out: &mut [HitRecord],
) -> Duration {
    assert_eq!(rays.len(), out.len());
    let start = Instant::now();
    pool.install(|| {
        out.par_chunks_mut(CHUNK)
            .zip(rays.par_chunks(CHUNK))
            .for_each(|(out, rays)| {
                for (o, r) in out.iter_mut().zip(rays) {
                    for _ in 0..runs {
                        // Opaque to the optimiser: every run is a query.
                        let r = std::hint::black_box(r);
                        *o = if occluded {
                            HitRecord::from_occluded(accel.occluded(r))
                        } else {
                            HitRecord::from_hit(accel.intersect(r))
                        };
                    }
                }
            })
    });
    start.elapsed()
}

/// Traces the rays as packets, one per group of ray indices (image tiles), into `out`.
pub fn trace_packets_into(
    accel: &dyn rt_packet::PacketAccel,
    rays: &[Ray],
    groups: &[Vec<usize>],
    occluded: bool,
    pool: &rayon::ThreadPool,
    out: &mut [HitRecord],
) -> Duration {
    assert_eq!(rays.len(), out.len());
    let start = Instant::now();
    let results: Vec<Vec<HitRecord>> = pool.install(|| {
        groups
            .par_iter()
            .map(|g| {
                let tile: Vec<Ray> = g.iter().map(|&i| rays[i]).collect();
                if occluded {
                    let mut b = vec![false; tile.len()];
                    accel.occluded_group(&tile, &mut b);
                    b.into_iter().map(HitRecord::from_occluded).collect()
                } else {
                    let mut h = vec![None; tile.len()];
                    accel.intersect_group(&tile, &mut h);
                    h.into_iter().map(HitRecord::from_hit).collect()
                }
            })
            .collect()
    });
    for (g, r) in groups.iter().zip(results) {
        for (&i, rec) in g.iter().zip(r) {
            out[i] = rec;
        }
    }
    start.elapsed()
}

/// Rays gathered group by group (image tiles, or the secondary rays of their pixels), so that
/// each group is a slice, as a renderer that makes its rays tile by tile has them.
pub struct GroupedRays {
    rays: Vec<Ray>,
    /// Group `k` is `rays[ends[k - 1]..ends[k]]` (from 0 for the first).
    ends: Vec<usize>,
}

impl GroupedRays {
    /// `groups` of indices into `rays`, gathered.
    pub fn new(rays: &[Ray], groups: &[Vec<usize>]) -> Self {
        let mut out = Self {
            rays: Vec::with_capacity(groups.iter().map(Vec::len).sum()),
            ends: Vec::with_capacity(groups.len()),
        };
        for g in groups {
            out.rays.extend(g.iter().map(|&i| rays[i]));
            out.ends.push(out.rays.len());
        }
        out
    }

    /// Number of rays in all groups.
    pub fn ray_count(&self) -> usize {
        self.rays.len()
    }

    /// Group `k`.
    fn group(&self, k: usize) -> &[Ray] {
        let start = if k == 0 { 0 } else { self.ends[k - 1] };
        &self.rays[start..self.ends[k]]
    }
}

/// Traces every group of rays as a packet (incoherent groups ray by ray, as
/// [`rt_packet::PacketAccel::intersect_group`] does) and counts hits, nothing stored: the
/// packet counterpart of [`trace_count`]. Returns `(hits, time)`.
pub fn trace_packets_count(
    accel: &dyn rt_packet::PacketAccel,
    grouped: &GroupedRays,
    occluded: bool,
    pool: &rayon::ThreadPool,
) -> (usize, Duration) {
    let largest = grouped.ends.iter().scan(0, |prev, &e| {
        let len = e - *prev;
        *prev = e;
        Some(len)
    });
    let per_task = (CHUNK / largest.max().unwrap_or(1).max(1)).max(1);
    let start = Instant::now();
    let hits = pool.install(|| {
        (0..grouped.ends.len())
            .into_par_iter()
            .with_min_len(per_task)
            .map_init(
                // Answer buffers per task, not per group (a 2x2 group would clear 256 slots).
                || {
                    (
                        vec![false; rt_packet::MAX_GROUP],
                        vec![None; rt_packet::MAX_GROUP],
                    )
                },
                |(blocked, hits), k| {
                    let rays = grouped.group(k);
                    if occluded {
                        let blocked = &mut blocked[..rays.len()];
                        accel.occluded_group(rays, blocked);
                        blocked.iter().filter(|&&b| b).count()
                    } else {
                        let hits = &mut hits[..rays.len()];
                        accel.intersect_group(rays, hits);
                        hits.iter().filter(|h| h.is_some()).count()
                    }
                },
            )
            .sum()
    });
    (hits, start.elapsed())
}

/// Traces every ray and counts hits (nothing stored); returns `(hits, time)`.
pub fn trace_count(
    accel: &dyn Accel,
    rays: &[Ray],
    occluded: bool,
    pool: &rayon::ThreadPool,
) -> (usize, Duration) {
    let start = Instant::now();
    let hits = pool.install(|| {
        rays.par_chunks(CHUNK)
            .map(|rays| count_hits(accel, rays, occluded))
            .sum()
    });
    (hits, start.elapsed())
}

/// Rays that hit (`intersect`), or that are occluded, on the calling thread.
#[inline]
pub fn count_hits(accel: &dyn Accel, rays: &[Ray], occluded: bool) -> usize {
    rays.iter()
        .filter(|r| {
            if occluded {
                accel.occluded(r)
            } else {
                accel.intersect(r).is_some()
            }
        })
        .count()
}

/// The median of a non-empty list of durations.
pub fn median(mut times: Vec<Duration>) -> Duration {
    times.sort();
    let n = times.len();
    if n % 2 == 1 {
        times[n / 2]
    } else {
        (times[n / 2 - 1] + times[n / 2]) / 2
    }
}

/// Millions of rays per second.
pub fn mrays_per_s(rays: usize, time: Duration) -> f64 {
    rays as f64 / time.as_secs_f64().max(1e-9) / 1e6
}

/// A spinner for work that may take a while (hidden when stderr is not a terminal).
pub fn spinner(msg: String) -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::new_spinner();
    pb.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {msg} {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    pb.set_message(msg);
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// A bar over `len` steps.
pub fn bar(len: u64, prefix: impl Into<String>) -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::new(len);
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:30}] {pos}/{len} {elapsed} {wide_msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    pb.set_prefix(prefix.into());
    pb
}
