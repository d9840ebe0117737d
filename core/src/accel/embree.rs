//! The optional Embree 3 backend of [`Accel`](super::Accel) (cargo feature `embree`, Debian's
//! `libembree-dev`): the same BVH-space triangles, handed to Embree as one unindexed triangle
//! geometry, so a hit's `primID` is the triangle's slot in `Accel::tris` and `Accel::refs`.
//!
//! Embree's traversal and its triangle test replace obvhs's and the watertight test:
//! - the scene is built with `RTC_SCENE_FLAG_ROBUST` (no hit lost on shared edges or to
//!   axis-parallel directions) by a one-thread device, so the hierarchy, and with it which of
//!   two triangles at exactly the same distance is reported, does not depend on the machine;
//! - queries run in BVH space (world × the power-of-two `scale`), the direction scaled the
//!   same way, so Embree's `t` is the world ray's parameter, and start `NEAR` (2⁻²⁰ of the
//!   scene's extent) along: the rays penumbra spawns leave their surface through
//!   `offset_ray_origin`, which puts their own triangle behind them or, on an axis-aligned
//!   face, exactly on it.
//!
//! Triangles of cut-out meshes (`alpha`, `shadowalpha`) form a second geometry whose filter
//! functions ask the query's alpha test ([`super::HitFilter`] through `Accel::accepts`) about
//! each candidate hit; the test travels with the query in an extended intersect context.

use glam::Vec3A;
use std::ffi::{c_char, c_uint, c_void};

#[allow(non_camel_case_types)]
type RTCDevice = *mut c_void;
#[allow(non_camel_case_types)]
type RTCScene = *mut c_void;
#[allow(non_camel_case_types)]
type RTCGeometry = *mut c_void;

const RTC_GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
const RTC_BUFFER_TYPE_INDEX: c_uint = 0;
const RTC_BUFFER_TYPE_VERTEX: c_uint = 1;
const RTC_FORMAT_UINT3: c_uint = 0x5003;
const RTC_FORMAT_FLOAT3: c_uint = 0x9003;
const RTC_SCENE_FLAG_ROBUST: c_uint = 1 << 2;
const RTC_BUILD_QUALITY_MEDIUM: c_uint = 1;
const RTC_INVALID_GEOMETRY_ID: c_uint = u32::MAX;
/// The geometry ids `build` attaches: the opaque triangles, then the cut-out ones.
const OPAQUE: c_uint = 0;

/// Where queries start, as a BVH-space distance (the scene's extent is about 1): 2⁻²⁰. A point on
/// an axis-aligned face has no rounding error, so [`offset_ray_origin`] leaves it on the face
/// (as pbrt-v3 does) and a ray leaving it finds its own triangle at `t = 0` exactly; obvhs's
/// path rejects that with pbrt-v3's conservative bound on `t`, Embree's test needs `tnear > 0`.
///
/// [`offset_ray_origin`]: crate::geometry::offset_ray_origin
const NEAR: f32 = 1.0 / (1 << 20) as f32;

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

#[repr(C, align(16))]
struct RtcRayHit {
    ray: RtcRay,
    hit: RtcHit,
}

/// `RTCIntersectContext` as Debian's Embree 3.13 lays it out (`RTC_MAX_INSTANCE_LEVEL_COUNT`
/// 1, `RTC_MIN_WIDTH` 0).
#[repr(C)]
struct RtcIntersectContext {
    flags: c_uint,
    filter: *const c_void,
    inst_id: [c_uint; 1],
}

/// A candidate hit's verdict: (slot, t, barycentrics) → whether it counts.
pub(super) type Accept<'a> = &'a dyn Fn(u32, f32, [f32; 3]) -> bool;

/// The context a query hands Embree: Embree's own, then what the filter functions need (Embree
/// passes the context pointer through to them unchanged, so they may read past its own part).
#[repr(C)]
struct QueryContext<'a> {
    rtc: RtcIntersectContext,
    /// The cut-out geometry's first slot.
    cutout_base: u32,
    accept: Option<Accept<'a>>,
}

impl<'a> QueryContext<'a> {
    /// `rtcInitIntersectContext`: incoherent rays, no context filter.
    fn new(cutout_base: u32, accept: Option<Accept<'a>>) -> Self {
        QueryContext {
            rtc: RtcIntersectContext { flags: 0, filter: std::ptr::null(), inst_id: [RTC_INVALID_GEOMETRY_ID] },
            cutout_base,
            accept,
        }
    }
}

/// `RTCFilterFunctionNArguments`.
#[repr(C)]
struct RtcFilterArgs {
    valid: *mut i32,
    geometry_user_ptr: *mut c_void,
    context: *mut RtcIntersectContext,
    ray: *mut RtcRay,
    hit: *mut RtcHit,
    n: c_uint,
}

/// The filter function of the cut-out geometry, for closest-hit and occlusion queries alike
/// (the query's `accept` knows which it answers): a rejected candidate is marked invalid and
/// Embree carries on past it.
unsafe extern "C" fn cutout_filter(args: *const RtcFilterArgs) {
    // SAFETY: Embree calls this with valid arguments for a query made by `EmbreeScene`, whose
    // context is always a `QueryContext` (its first field is Embree's context); single-ray
    // queries (`rtcIntersect1`/`rtcOccluded1`) give N = 1, whose SOA ray and hit are laid out
    // as `RTCRay`/`RTCHit`.
    unsafe {
        let a = &*args;
        if a.n != 1 {
            return;
        }
        let ctx = &*(a.context as *const QueryContext);
        let Some(accept) = ctx.accept else { return };
        let (ray, hit) = (&*a.ray, &*a.hit);
        let slot = ctx.cutout_base + hit.prim_id;
        if !accept(slot, ray.tfar, [1.0 - hit.u - hit.v, hit.u, hit.v]) {
            *a.valid = 0;
        }
    }
}

#[link(name = "embree3")]
extern "C" {
    fn rtcNewDevice(config: *const c_char) -> RTCDevice;
    fn rtcReleaseDevice(device: RTCDevice);
    fn rtcGetDeviceError(device: RTCDevice) -> c_uint;
    fn rtcNewScene(device: RTCDevice) -> RTCScene;
    fn rtcSetSceneFlags(scene: RTCScene, flags: c_uint);
    fn rtcSetSceneBuildQuality(scene: RTCScene, quality: c_uint);
    fn rtcCommitScene(scene: RTCScene);
    fn rtcReleaseScene(scene: RTCScene);
    fn rtcNewGeometry(device: RTCDevice, kind: c_uint) -> RTCGeometry;
    fn rtcSetSharedGeometryBuffer(
        geometry: RTCGeometry,
        kind: c_uint,
        slot: c_uint,
        format: c_uint,
        ptr: *const c_void,
        byte_offset: usize,
        byte_stride: usize,
        item_count: usize,
    );
    fn rtcCommitGeometry(geometry: RTCGeometry);
    fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;
    fn rtcReleaseGeometry(geometry: RTCGeometry);
    fn rtcSetGeometryIntersectFilterFunction(geometry: RTCGeometry, filter: unsafe extern "C" fn(*const RtcFilterArgs));
    fn rtcSetGeometryOccludedFilterFunction(geometry: RTCGeometry, filter: unsafe extern "C" fn(*const RtcFilterArgs));
    fn rtcIntersect1(scene: RTCScene, context: *mut RtcIntersectContext, rayhit: *mut RtcRayHit);
    fn rtcOccluded1(scene: RTCScene, context: *mut RtcIntersectContext, ray: *mut RtcRay);
}

/// An Embree scene over `Accel`'s triangles. Both buffers are shared with Embree (not
/// copied): the vertices are `Accel::tris` itself, the index buffer lives here, boxed.
pub(super) struct EmbreeScene {
    device: RTCDevice,
    scene: RTCScene,
    _indices: Box<[[u32; 3]]>,
    /// The first slot of the cut-out triangles (geometry 1).
    cutout_base: u32,
}

// Embree's committed scenes are safe to query from any number of threads at once, and
// nothing here is mutated after `build`.
unsafe impl Send for EmbreeScene {}
unsafe impl Sync for EmbreeScene {}

impl EmbreeScene {
    /// `None` when Embree cannot make a device or the triangles do not fit its 32-bit ids.
    /// `tris[..opaque]` are opaque, the rest belong to cut-out meshes (alpha-tested through the
    /// query's `accept`).
    ///
    /// # Safety
    /// Embree reads `tris` in place for every query: the caller keeps that memory alive and
    /// unchanged until the returned scene is dropped (`Accel` holds both, the scene dropped
    /// first).
    pub(super) unsafe fn build(tris: &[[Vec3A; 3]], opaque: usize) -> Option<EmbreeScene> {
        let n = tris.len();
        if n == 0 || 3 * n >= u32::MAX as usize || opaque > n {
            return None;
        }
        // The triangles' vertices in a row, 16 bytes each (Vec3A, with 4 readable padding
        // bytes, as Embree's float3 buffers, read with 16-byte loads, want).
        let vertices: &[Vec3A] = tris.as_flattened();
        let indices: Box<[[u32; 3]]> = (0..n as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        // SAFETY: the FFI calls follow Embree 3's API: every handle is checked before use; the
        // index buffer is owned by the returned value, the vertices by the caller (see above).
        unsafe {
            let device = rtcNewDevice(c"threads=1,verbose=0".as_ptr());
            if device.is_null() {
                return None;
            }
            let scene = rtcNewScene(device);
            if scene.is_null() {
                rtcReleaseDevice(device);
                return None;
            }
            // Geometry 0 (OPAQUE): the opaque triangles; geometry 1: the cut-out ones, filtered.
            for (range, cutout) in [(0..opaque, false), (opaque..n, true)] {
                if range.is_empty() && cutout {
                    continue;
                }
                let geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
                if geometry.is_null() {
                    rtcReleaseScene(scene);
                    rtcReleaseDevice(device);
                    return None;
                }
                rtcSetSharedGeometryBuffer(
                    geometry,
                    RTC_BUFFER_TYPE_VERTEX,
                    0,
                    RTC_FORMAT_FLOAT3,
                    vertices.as_ptr().cast(),
                    0,
                    std::mem::size_of::<Vec3A>(),
                    vertices.len(),
                );
                rtcSetSharedGeometryBuffer(
                    geometry,
                    RTC_BUFFER_TYPE_INDEX,
                    0,
                    RTC_FORMAT_UINT3,
                    indices.as_ptr().cast(),
                    range.start * std::mem::size_of::<[u32; 3]>(),
                    std::mem::size_of::<[u32; 3]>(),
                    range.len(),
                );
                if cutout {
                    rtcSetGeometryIntersectFilterFunction(geometry, cutout_filter);
                    rtcSetGeometryOccludedFilterFunction(geometry, cutout_filter);
                }
                rtcCommitGeometry(geometry);
                rtcAttachGeometry(scene, geometry);
                rtcReleaseGeometry(geometry);
            }
            rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
            rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
            rtcCommitScene(scene);
            if rtcGetDeviceError(device) != 0 {
                rtcReleaseScene(scene);
                rtcReleaseDevice(device);
                return None;
            }
            Some(EmbreeScene { device, scene, _indices: indices, cutout_base: opaque as u32 })
        }
    }

    fn ray(o: Vec3A, d: Vec3A, t_max: f32) -> RtcRay {
        RtcRay {
            org: o.to_array(),
            tnear: NEAR / d.length(),
            dir: d.to_array(),
            time: 0.0,
            tfar: t_max,
            mask: u32::MAX,
            id: 0,
            flags: 0,
        }
    }

    /// The closest hit with `0 < t < t_max` of the BVH-space ray `o + t d` that `accept`
    /// takes (asked about cut-out triangles only; none: all count): the slot, `t` and the
    /// barycentrics of vertices 0, 1, 2.
    pub(super) fn intersect(
        &self,
        o: Vec3A,
        d: Vec3A,
        t_max: f32,
        accept: Option<Accept>,
    ) -> Option<(u32, f32, [f32; 3])> {
        let mut rh = RtcRayHit {
            ray: Self::ray(o, d, t_max),
            hit: RtcHit {
                ng: [0.0; 3],
                u: 0.0,
                v: 0.0,
                prim_id: RTC_INVALID_GEOMETRY_ID,
                geom_id: RTC_INVALID_GEOMETRY_ID,
                inst_id: [RTC_INVALID_GEOMETRY_ID],
            },
        };
        let mut context = QueryContext::new(self.cutout_base, accept);
        // SAFETY: a committed scene, a properly aligned ray/hit and a context that starts with
        // Embree's (`repr(C)`), which the filter function reads back as a `QueryContext`.
        unsafe { rtcIntersect1(self.scene, &mut context.rtc, &mut rh) };
        if rh.hit.geom_id == RTC_INVALID_GEOMETRY_ID {
            return None;
        }
        let base = if rh.hit.geom_id == OPAQUE { 0 } else { self.cutout_base };
        let (u, v) = (rh.hit.u, rh.hit.v);
        Some((base + rh.hit.prim_id, rh.ray.tfar, [1.0 - u - v, u, v]))
    }

    /// Whether anything `accept` takes lies on the BVH-space ray `o + t d` with
    /// `0 < t < t_max`.
    pub(super) fn occluded(&self, o: Vec3A, d: Vec3A, t_max: f32, accept: Option<Accept>) -> bool {
        let mut ray = Self::ray(o, d, t_max);
        let mut context = QueryContext::new(self.cutout_base, accept);
        // SAFETY: as `intersect`.
        unsafe { rtcOccluded1(self.scene, &mut context.rtc, &mut ray) };
        // Embree sets tfar to -inf on a hit.
        ray.tfar < 0.0
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: the handles were made by `build` and are released once.
        unsafe {
            rtcReleaseScene(self.scene);
            rtcReleaseDevice(self.device);
        }
    }
}
