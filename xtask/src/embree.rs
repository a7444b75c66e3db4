//! Intel Embree 3 behind the `Accel` trait (Cargo feature `embree`; Debian's `libembree-dev`).
//!
//! A small FFI module of our own, of the few calls rt needs: a device with `threads=N`, one
//! triangle geometry with shared vertex and index buffers, a scene built at a chosen quality
//! with or without the robust flag ([`EmbreeMode`]), `rtcIntersect1` / `rtcOccluded1` and the
//! 8-ray packets. Struct layouts follow Embree 3.13's headers (`RTC_MAX_INSTANCE_LEVEL_COUNT`
//! 1, `RTC_MIN_WIDTH` 0) and are checked at compile time.

use rt_geom::{Accel, AccelStats, BuildError, Hit, Ray, Triangle, check_primitives};
use std::ffi::{CStr, c_char, c_uint, c_void};
use std::ptr::NonNull;

#[repr(C)]
struct RtcIntersectContext {
    flags: c_uint,
    filter: *const c_void,
    inst_id: [c_uint; 1],
}

#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct RtcRay {
    org: [f32; 3],
    tnear: f32,
    dir: [f32; 3],
    time: f32,
    tfar: f32,
    mask: c_uint,
    id: c_uint,
    flags: c_uint,
}

#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct RtcHit {
    ng: [f32; 3],
    u: f32,
    v: f32,
    prim_id: c_uint,
    geom_id: c_uint,
    inst_id: [c_uint; 1],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct RtcRayHit {
    ray: RtcRay,
    hit: RtcHit,
}

/// Eight rays, structure of arrays (`RTCRay8`).
#[repr(C, align(32))]
#[derive(Clone, Copy)]
struct RtcRay8 {
    org: [[f32; 8]; 3],
    tnear: [f32; 8],
    dir: [[f32; 8]; 3],
    time: [f32; 8],
    tfar: [f32; 8],
    mask: [c_uint; 8],
    id: [c_uint; 8],
    flags: [c_uint; 8],
}

/// Eight hits (`RTCHit8`).
#[repr(C, align(32))]
#[derive(Clone, Copy)]
struct RtcHit8 {
    ng: [[f32; 8]; 3],
    u: [f32; 8],
    v: [f32; 8],
    prim_id: [c_uint; 8],
    geom_id: [c_uint; 8],
    inst_id: [[c_uint; 8]; 1],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct RtcRayHit8 {
    ray: RtcRay8,
    hit: RtcHit8,
}

/// The `valid` mask of the packet calls: -1 for an active lane.
#[repr(C, align(32))]
struct Valid8([i32; 8]);

const _: () = assert!(size_of::<RtcRay8>() == 384);
const _: () = assert!(size_of::<RtcHit8>() == 256);
const _: () = assert!(size_of::<RtcRayHit8>() == 640);
const _: () = assert!(size_of::<RtcIntersectContext>() == 24);
const _: () = assert!(size_of::<RtcRay>() == 48);
const _: () = assert!(size_of::<RtcHit>() == 32);
const _: () = assert!(size_of::<RtcRayHit>() == 80);

const INVALID_GEOMETRY_ID: c_uint = u32::MAX;
const GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
const BUFFER_TYPE_INDEX: c_uint = 0;
const BUFFER_TYPE_VERTEX: c_uint = 1;
const FORMAT_UINT3: c_uint = 0x5003;
const FORMAT_FLOAT3: c_uint = 0x9003;
const BUILD_QUALITY_MEDIUM: c_uint = 1;
const BUILD_QUALITY_HIGH: c_uint = 2;
const SCENE_FLAG_ROBUST: c_uint = 1 << 2;

#[link(name = "embree3")]
unsafe extern "C" {
    fn rtcNewDevice(config: *const c_char) -> *mut c_void;
    fn rtcReleaseDevice(device: *mut c_void);
    fn rtcGetDeviceError(device: *mut c_void) -> c_uint;
    fn rtcNewScene(device: *mut c_void) -> *mut c_void;
    fn rtcReleaseScene(scene: *mut c_void);
    fn rtcSetSceneBuildQuality(scene: *mut c_void, quality: c_uint);
    fn rtcSetSceneFlags(scene: *mut c_void, flags: c_uint);
    fn rtcCommitScene(scene: *mut c_void);
    fn rtcNewGeometry(device: *mut c_void, kind: c_uint) -> *mut c_void;
    fn rtcSetGeometryBuildQuality(geometry: *mut c_void, quality: c_uint);
    fn rtcSetNewGeometryBuffer(
        geometry: *mut c_void,
        kind: c_uint,
        slot: c_uint,
        format: c_uint,
        byte_stride: usize,
        item_count: usize,
    ) -> *mut c_void;
    fn rtcCommitGeometry(geometry: *mut c_void);
    fn rtcAttachGeometry(scene: *mut c_void, geometry: *mut c_void) -> c_uint;
    fn rtcReleaseGeometry(geometry: *mut c_void);
    fn rtcIntersect1(scene: *mut c_void, context: *mut RtcIntersectContext, rayhit: *mut RtcRayHit);
    fn rtcOccluded1(scene: *mut c_void, context: *mut RtcIntersectContext, ray: *mut RtcRay);
    fn rtcIntersect8(
        valid: *const i32,
        scene: *mut c_void,
        context: *mut RtcIntersectContext,
        rayhit: *mut RtcRayHit8,
    );
    fn rtcOccluded8(
        valid: *const i32,
        scene: *mut c_void,
        context: *mut RtcIntersectContext,
        ray: *mut RtcRay8,
    );
}

/// An Embree scene of triangles (ids are the caller's indices).
pub struct EmbreeScene {
    device: NonNull<c_void>,
    scene: NonNull<c_void>,
    prims: usize,
    threads: usize,
}

// SAFETY: Embree scenes are immutable after `rtcCommitScene`, and `rtcIntersect1` /
// `rtcOccluded1` may be called on one scene from any number of threads at once (Embree 3 API
// documentation, "Thread safety"); the device is only released in `Drop`.
unsafe impl Send for EmbreeScene {}
// SAFETY: as above.
unsafe impl Sync for EmbreeScene {}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: both handles were created by this value and are released once, scene first.
        unsafe {
            rtcReleaseScene(self.scene.as_ptr());
            rtcReleaseDevice(self.device.as_ptr());
        }
    }
}

/// Embree's device held to the instruction set `RT_ISA` holds rt to (`,isa=avx2` and so on),
/// so that both engines can be compared on the same level; nothing when `RT_ISA` is unset
/// (Embree then picks the best its build has for this CPU).
fn isa_config() -> String {
    let Some(isa) = std::env::var("RT_ISA")
        .ok()
        .and_then(|v| rt_geom::Isa::parse(&v).ok())
    else {
        return String::new();
    };
    let name = match isa {
        rt_geom::Isa::Baseline => "sse2",
        rt_geom::Isa::Avx2 => "avx2",
        // Embree's own best, its AVX-512 kernels where the CPU has them.
        rt_geom::Isa::Avx512 => return String::new(),
    };
    format!(",isa={name}")
}

fn error(what: &str) -> BuildError {
    BuildError::InvalidParameter {
        name: "embree",
        value: what.to_string(),
        expected: "a working Embree 3 device",
    }
}

/// How an Embree scene is built: its scene flags and build quality.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmbreeMode {
    /// High quality with `RTC_SCENE_FLAG_ROBUST`: the mode held to rt's answers.
    Robust,
    /// High quality with Embree's default scene flags: the faster mode most of its users run.
    Default,
    /// Medium quality (Embree's default build) with its default scene flags: the build-time
    /// reference.
    Medium,
}

impl EmbreeScene {
    /// Builds in `mode` with `threads` build threads (0: rayon's current pool size).
    pub fn build(tris: &[Triangle], threads: usize, mode: EmbreeMode) -> Result<Self, BuildError> {
        let (robust, quality) = match mode {
            EmbreeMode::Robust => (true, BUILD_QUALITY_HIGH),
            EmbreeMode::Default => (false, BUILD_QUALITY_HIGH),
            EmbreeMode::Medium => (false, BUILD_QUALITY_MEDIUM),
        };
        check_primitives(tris, u32::MAX as usize)?;
        let threads = if threads == 0 {
            rayon::current_num_threads()
        } else {
            threads
        };
        let config = format!("threads={threads},verbose=0{}\0", isa_config());
        let config = CStr::from_bytes_with_nul(config.as_bytes()).map_err(|_| error("config"))?;
        // SAFETY: a valid NUL-terminated configuration string.
        let device = NonNull::new(unsafe { rtcNewDevice(config.as_ptr()) })
            .ok_or_else(|| error("rtcNewDevice failed"))?;
        // SAFETY: `device` is a live device; every handle below comes from it, buffers are
        // written within the sizes Embree allocated for them, and errors are checked before
        // the scene is used.
        unsafe {
            let Some(scene) = NonNull::new(rtcNewScene(device.as_ptr())) else {
                rtcReleaseDevice(device.as_ptr());
                return Err(error("rtcNewScene failed"));
            };
            let out = Self {
                device,
                scene,
                prims: tris.len(),
                threads,
            };
            rtcSetSceneBuildQuality(scene.as_ptr(), quality);
            if robust {
                rtcSetSceneFlags(scene.as_ptr(), SCENE_FLAG_ROBUST);
            }
            if !tris.is_empty() {
                let geometry = rtcNewGeometry(device.as_ptr(), GEOMETRY_TYPE_TRIANGLE);
                if geometry.is_null() {
                    return Err(error("rtcNewGeometry failed"));
                }
                rtcSetGeometryBuildQuality(geometry, quality);
                let n = tris.len();
                let vertices = rtcSetNewGeometryBuffer(
                    geometry,
                    BUFFER_TYPE_VERTEX,
                    0,
                    FORMAT_FLOAT3,
                    12,
                    3 * n,
                ) as *mut f32;
                let indices =
                    rtcSetNewGeometryBuffer(geometry, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3, 12, n)
                        as *mut u32;
                if vertices.is_null() || indices.is_null() {
                    rtcReleaseGeometry(geometry);
                    return Err(error("geometry buffers could not be allocated"));
                }
                let vertices = std::slice::from_raw_parts_mut(vertices, 9 * n);
                let indices = std::slice::from_raw_parts_mut(indices, 3 * n);
                for (i, t) in tris.iter().enumerate() {
                    for (k, v) in t.v.iter().enumerate() {
                        vertices[9 * i + 3 * k..9 * i + 3 * k + 3].copy_from_slice(&v.to_array());
                        indices[3 * i + k] = (3 * i + k) as u32;
                    }
                }
                rtcCommitGeometry(geometry);
                rtcAttachGeometry(scene.as_ptr(), geometry);
                rtcReleaseGeometry(geometry);
            }
            rtcCommitScene(scene.as_ptr());
            match rtcGetDeviceError(device.as_ptr()) {
                0 => Ok(out),
                code => Err(error(&format!("Embree error code {code} while building"))),
            }
        }
    }

    fn context() -> RtcIntersectContext {
        RtcIntersectContext {
            flags: 0,
            filter: std::ptr::null(),
            inst_id: [INVALID_GEOMETRY_ID],
        }
    }

    fn ray(ray: &Ray) -> RtcRay {
        RtcRay {
            org: ray.origin().to_array(),
            tnear: ray.tmin.max(0.0),
            dir: ray.dir().to_array(),
            time: 0.0,
            tfar: ray.tmax,
            mask: u32::MAX,
            id: 0,
            flags: 0,
        }
    }
}

/// Up to eight rays as Embree's SoA packet and its `valid` mask (invalid rays are inactive).
fn packet8(rays: &[Ray]) -> (Valid8, RtcRay8) {
    let mut valid = Valid8([0; 8]);
    let mut r = RtcRay8 {
        org: [[0.0; 8]; 3],
        tnear: [0.0; 8],
        dir: [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0; 8], [1.0; 8]],
        time: [0.0; 8],
        tfar: [0.0; 8],
        mask: [u32::MAX; 8],
        id: [0; 8],
        flags: [0; 8],
    };
    for (i, ray) in rays.iter().enumerate().take(8) {
        let one = EmbreeScene::ray(ray);
        for a in 0..3 {
            r.org[a][i] = one.org[a];
            r.dir[a][i] = one.dir[a];
        }
        r.tnear[i] = one.tnear;
        r.tfar[i] = one.tfar;
        if ray.is_valid() && ray.tmin <= ray.tmax {
            valid.0[i] = -1;
        }
    }
    (valid, r)
}

/// `rtcIntersect8` / `rtcOccluded8` over groups of 8 rays (4x2 pixel tiles with
/// `trace --packet 4x2`): Embree's own packet path, for the packet comparisons.
impl rt_packet::PacketAccel for EmbreeScene {
    fn intersect_packet_group(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), out.len());
        for (rays, out) in rays.chunks(8).zip(out.chunks_mut(8)) {
            let (valid, ray) = packet8(rays);
            let mut rh = RtcRayHit8 {
                ray,
                hit: RtcHit8 {
                    ng: [[0.0; 8]; 3],
                    u: [0.0; 8],
                    v: [0.0; 8],
                    prim_id: [INVALID_GEOMETRY_ID; 8],
                    geom_id: [INVALID_GEOMETRY_ID; 8],
                    inst_id: [[INVALID_GEOMETRY_ID; 8]],
                },
            };
            if self.prims > 0 {
                let mut context = Self::context();
                // SAFETY: a committed scene, an initialised context, a 32-byte aligned valid
                // mask and ray/hit packet of 8 lanes.
                unsafe {
                    rtcIntersect8(valid.0.as_ptr(), self.scene.as_ptr(), &mut context, &mut rh)
                };
            }
            for (i, o) in out.iter_mut().enumerate() {
                *o = (valid.0[i] != 0 && rh.hit.geom_id[i] != INVALID_GEOMETRY_ID).then_some(Hit {
                    t: rh.ray.tfar[i],
                    u: rh.hit.u[i],
                    v: rh.hit.v[i],
                    prim: rh.hit.prim_id[i],
                });
            }
        }
    }

    fn occluded_packet_group(&self, rays: &[Ray], out: &mut [bool]) {
        assert_eq!(rays.len(), out.len());
        for (rays, out) in rays.chunks(8).zip(out.chunks_mut(8)) {
            let (valid, mut ray) = packet8(rays);
            if self.prims > 0 {
                let mut context = Self::context();
                // SAFETY: as in `intersect_packet_group`; occluded lanes get `tfar = -inf`.
                unsafe {
                    rtcOccluded8(
                        valid.0.as_ptr(),
                        self.scene.as_ptr(),
                        &mut context,
                        &mut ray,
                    )
                };
            }
            for (i, o) in out.iter_mut().enumerate() {
                *o = valid.0[i] != 0 && self.prims > 0 && ray.tfar[i] == f32::NEG_INFINITY;
            }
        }
    }
}

impl Accel for EmbreeScene {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_valid() || self.prims == 0 || !(ray.tmin <= ray.tmax) {
            return None;
        }
        let mut rh = RtcRayHit {
            ray: Self::ray(ray),
            hit: RtcHit {
                ng: [0.0; 3],
                u: 0.0,
                v: 0.0,
                prim_id: INVALID_GEOMETRY_ID,
                geom_id: INVALID_GEOMETRY_ID,
                inst_id: [INVALID_GEOMETRY_ID],
            },
        };
        let mut context = Self::context();
        // SAFETY: a committed scene, an initialised context and a 16-byte aligned ray/hit.
        unsafe { rtcIntersect1(self.scene.as_ptr(), &mut context, &mut rh) };
        (rh.hit.geom_id != INVALID_GEOMETRY_ID).then_some(Hit {
            t: rh.ray.tfar,
            u: rh.hit.u,
            v: rh.hit.v,
            prim: rh.hit.prim_id,
        })
    }

    fn occluded(&self, ray: &Ray) -> bool {
        if !ray.is_valid() || self.prims == 0 || !(ray.tmin <= ray.tmax) {
            return false;
        }
        let mut r = Self::ray(ray);
        let mut context = Self::context();
        // SAFETY: as in `intersect`; Embree sets `tfar` to -inf when the ray is occluded.
        unsafe { rtcOccluded1(self.scene.as_ptr(), &mut context, &mut r) };
        r.tfar == f32::NEG_INFINITY
    }

    fn stats(&self) -> AccelStats {
        crate::registry::opaque_peer_stats(self.prims)
    }

    fn validate(&self) -> Result<(), String> {
        (self.threads > 0)
            .then_some(())
            .ok_or_else(|| "no build threads".into())
    }
}
