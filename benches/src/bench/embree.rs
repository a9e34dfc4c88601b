//! Intel Embree 3 as a peer: hand-written FFI for the dozen functions the benchmark needs
//! (feature `embree`; Debian: `apt-get install libembree-dev`, Embree 3.13.5).
//!
//! Struct layouts follow `/usr/include/embree3/rtcore_ray.h` and `rtcore_common.h` for
//! `RTC_MAX_INSTANCE_LEVEL_COUNT == 1` and `RTC_MIN_WIDTH == 0` (Debian's build): `RTCRay`
//! 48 bytes (16-aligned), `RTCHit` 32 bytes, `RTCRay8` 384 bytes (32-aligned), `RTCRayHit8`
//! 640 bytes, `RTCIntersectContext` 24 bytes (flags, filter pointer, one instance id).
//! The sizes are checked at compile time below.
//!
//! The scene holds hyrt's traceable triangles (the ones in hyrt's BVH) as one triangle
//! mesh, each triangle with its own three vertices, so Embree's `primID` maps back to
//! hyrt's global triangle index. Build quality and scene flags are Embree's defaults
//! (medium quality, not `RTC_SCENE_FLAG_ROBUST`): the fast path Embree is known for.
//! Embree's triangle test is not watertight, so a few rays on shared edges may differ
//! from hyrt's watertight test; the benchmark counts them.
//!
//! Ray semantics: hyrt hits `t_min < t < t_max` with unnormalized directions; Embree
//! hits `tnear <= t <= tfar` with the same parametrization, so the only possible
//! difference is a hit exactly at an end point.

use std::ffi::{c_char, c_int, c_uint, c_void};

use hyrt_core::bvh::triangle_is_traceable;
use hyrt_core::formats::RayRecord;
use hyrt_core::geometry::WorldGeometry;
use hyrt_core::glam::Mat4;
use hyrt_core::scene::Scene;

type RTCDevice = *mut c_void;
type RTCScene = *mut c_void;
type RTCGeometry = *mut c_void;

/// `RTC_INVALID_GEOMETRY_ID`.
const RTC_INVALID_GEOMETRY_ID: u32 = u32::MAX;
/// `RTC_GEOMETRY_TYPE_TRIANGLE`.
const RTC_GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
/// `RTC_GEOMETRY_TYPE_INSTANCE`: an instance of another scene (`rtcore_geometry.h`).
const RTC_GEOMETRY_TYPE_INSTANCE: c_uint = 121;
/// `RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR` (0x9234; 0x9134 is the row-major one): an instance's
/// local-to-world transform as 12 floats, the columns x, y, z and the translation.
const RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR: c_uint = 0x9234;
/// `RTC_SCENE_FLAG_DYNAMIC` and `RTC_BUILD_QUALITY_LOW`: what Embree advises for a scene
/// committed again every frame (`rtcore_scene.h`, `rtcore_common.h`).
const RTC_SCENE_FLAG_DYNAMIC: c_uint = 1;
const RTC_BUILD_QUALITY_LOW: c_uint = 0;
/// `RTC_BUFFER_TYPE_INDEX`, `RTC_BUFFER_TYPE_VERTEX`.
const RTC_BUFFER_TYPE_INDEX: c_uint = 0;
const RTC_BUFFER_TYPE_VERTEX: c_uint = 1;
/// `RTC_FORMAT_UINT3` (0x5003) and `RTC_FORMAT_FLOAT3` (0x9003).
const RTC_FORMAT_UINT3: c_uint = 0x5003;
const RTC_FORMAT_FLOAT3: c_uint = 0x9003;
/// `RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT`: what `rtcInitIntersectContext` sets.
const RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT: c_uint = 0;
/// `RTC_INTERSECT_CONTEXT_FLAG_COHERENT`: the rays of a packet are coherent (Embree may then
/// trace a packet with its frustum-based coherent traversal).
const RTC_INTERSECT_CONTEXT_FLAG_COHERENT: c_uint = 1;
/// Packet width of [`EmbreeScene::occluded8`] and [`EmbreeScene::intersect8`].
pub const PACKET: usize = 8;

#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
struct RTCRay {
    org: [f32; 3],
    tnear: f32,
    dir: [f32; 3],
    time: f32,
    tfar: f32,
    mask: u32,
    id: u32,
    flags: u32,
}

#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
struct RTCHit {
    ng: [f32; 3],
    u: f32,
    v: f32,
    prim_id: u32,
    geom_id: u32,
    inst_id: [u32; 1],
}

#[repr(C)]
#[derive(Clone, Copy, Default)]
struct RTCRayHit {
    ray: RTCRay,
    hit: RTCHit,
}

#[repr(C, align(32))]
#[derive(Clone, Copy, Default)]
struct RTCRay8 {
    org_x: [f32; 8],
    org_y: [f32; 8],
    org_z: [f32; 8],
    tnear: [f32; 8],
    dir_x: [f32; 8],
    dir_y: [f32; 8],
    dir_z: [f32; 8],
    time: [f32; 8],
    tfar: [f32; 8],
    mask: [u32; 8],
    id: [u32; 8],
    flags: [u32; 8],
}

#[repr(C, align(32))]
#[derive(Clone, Copy, Default)]
struct RTCHit8 {
    ng_x: [f32; 8],
    ng_y: [f32; 8],
    ng_z: [f32; 8],
    u: [f32; 8],
    v: [f32; 8],
    prim_id: [u32; 8],
    geom_id: [u32; 8],
    inst_id: [[u32; 8]; 1],
}

#[repr(C)]
#[derive(Clone, Copy, Default)]
struct RTCRayHit8 {
    ray: RTCRay8,
    hit: RTCHit8,
}

#[repr(C)]
struct RTCIntersectContext {
    flags: c_uint,
    filter: *const c_void,
    inst_id: [u32; 1],
}

/// The `valid` mask of a packet call: -1 active, 0 inactive (32-byte aligned).
#[repr(C, align(32))]
struct Valid8([c_int; 8]);

const _: () = {
    assert!(std::mem::size_of::<RTCRay>() == 48);
    assert!(std::mem::size_of::<RTCHit>() == 32);
    assert!(std::mem::size_of::<RTCRayHit>() == 80);
    assert!(std::mem::size_of::<RTCRay8>() == 384);
    assert!(std::mem::size_of::<RTCRayHit8>() == 640);
    assert!(std::mem::offset_of!(RTCRayHit8, hit) == 384);
    assert!(std::mem::size_of::<RTCIntersectContext>() == 24);
    assert!(std::mem::offset_of!(RTCIntersectContext, filter) == 8);
};

#[link(name = "embree3")]
extern "C" {
    fn rtcNewDevice(config: *const c_char) -> RTCDevice;
    fn rtcReleaseDevice(device: RTCDevice);
    fn rtcGetDeviceError(device: RTCDevice) -> c_uint;
    fn rtcGetDeviceProperty(device: RTCDevice, prop: c_uint) -> isize;
    fn rtcNewScene(device: RTCDevice) -> RTCScene;
    fn rtcReleaseScene(scene: RTCScene);
    fn rtcNewGeometry(device: RTCDevice, kind: c_uint) -> RTCGeometry;
    fn rtcReleaseGeometry(geometry: RTCGeometry);
    fn rtcSetNewGeometryBuffer(
        geometry: RTCGeometry,
        kind: c_uint,
        slot: c_uint,
        format: c_uint,
        byte_stride: usize,
        item_count: usize,
    ) -> *mut c_void;
    fn rtcCommitGeometry(geometry: RTCGeometry);
    fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;
    fn rtcCommitScene(scene: RTCScene);
    fn rtcSetSceneFlags(scene: RTCScene, flags: c_uint);
    fn rtcSetSceneBuildQuality(scene: RTCScene, quality: c_uint);
    fn rtcSetGeometryInstancedScene(geometry: RTCGeometry, scene: RTCScene);
    fn rtcSetGeometryTransform(geometry: RTCGeometry, time_step: c_uint, format: c_uint, xfm: *const c_void);
    fn rtcOccluded1(scene: RTCScene, context: *mut RTCIntersectContext, ray: *mut RTCRay);
    fn rtcOccluded8(valid: *const c_int, scene: RTCScene, context: *mut RTCIntersectContext, ray: *mut RTCRay8);
    fn rtcIntersect1(scene: RTCScene, context: *mut RTCIntersectContext, rayhit: *mut RTCRayHit);
    fn rtcIntersect8(valid: *const c_int, scene: RTCScene, context: *mut RTCIntersectContext, rayhit: *mut RTCRayHit8);
}

/// `rtcInitIntersectContext` is a static inline function in the header; this is its body
/// for `RTC_MAX_INSTANCE_LEVEL_COUNT == 1`, `RTC_MIN_WIDTH == 0`.
fn init_context() -> RTCIntersectContext {
    context(false)
}

fn context(coherent: bool) -> RTCIntersectContext {
    RTCIntersectContext {
        flags: if coherent { RTC_INTERSECT_CONTEXT_FLAG_COHERENT } else { RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT },
        filter: std::ptr::null(),
        inst_id: [RTC_INVALID_GEOMETRY_ID],
    }
}

/// Embree failed (device creation or a call that set the device error).
#[derive(Debug, thiserror::Error)]
#[error("Embree: {0}")]
pub struct EmbreeError(String);

/// An Embree device and a committed scene of hyrt's traceable triangles.
pub struct EmbreeScene {
    device: RTCDevice,
    scene: RTCScene,
    /// Embree `primID` -> hyrt global triangle index.
    pub prim_to_triangle: Vec<u32>,
    /// Milliseconds `rtcCommitScene` took (Embree's BVH build).
    pub build_ms: f64,
}

// SAFETY: after rtcCommitScene an Embree scene is immutable and its query functions
// (rtcOccluded*, rtcIntersect*) may be called from any number of threads at once
// (Embree 3 API documentation, "Thread safety"); the device is only released on drop.
unsafe impl Send for EmbreeScene {}
unsafe impl Sync for EmbreeScene {}

fn device_error(device: RTCDevice, what: &str) -> Result<(), EmbreeError> {
    // SAFETY: `device` is a live device.
    let code = unsafe { rtcGetDeviceError(device) };
    if code == 0 {
        Ok(())
    } else {
        Err(EmbreeError(format!("{what} failed with RTCError {code}")))
    }
}

/// A device created with `config` (e.g. `"threads=2"`).
fn new_device(config: &str) -> Result<RTCDevice, EmbreeError> {
    let config = std::ffi::CString::new(config).map_err(|_| EmbreeError("config contains a NUL".into()))?;
    // SAFETY: a NUL-terminated config string.
    let device = unsafe { rtcNewDevice(config.as_ptr()) };
    if device.is_null() {
        return Err(EmbreeError("rtcNewDevice returned null".into()));
    }
    Ok(device)
}

/// A committed (not attached) triangle geometry of `n` triangles, each with its own three
/// vertices `corners(p)`, so that Embree's `primID` is `p`. The caller attaches and
/// releases it.
///
/// # Safety
/// `device` is a live device.
unsafe fn triangle_geometry(
    device: RTCDevice,
    n: usize,
    corners: impl Fn(usize) -> [[f32; 3]; 3],
) -> Result<RTCGeometry, EmbreeError> {
    let geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    device_error(device, "rtcNewGeometry")?;
    let vb = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 3 * n) as *mut [f32; 3];
    let ib = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, n) as *mut [u32; 3];
    if vb.is_null() || ib.is_null() {
        rtcReleaseGeometry(geom);
        return Err(EmbreeError("rtcSetNewGeometryBuffer returned null".into()));
    }
    // SAFETY: the buffers hold 3n vertices and n index triples (the sizes just passed).
    let vb = std::slice::from_raw_parts_mut(vb, 3 * n);
    let ib = std::slice::from_raw_parts_mut(ib, n);
    for p in 0..n {
        vb[3 * p..3 * p + 3].copy_from_slice(&corners(p));
        let b = 3 * p as u32;
        ib[p] = [b, b + 1, b + 2];
    }
    rtcCommitGeometry(geom);
    device_error(device, "building a triangle geometry")?;
    Ok(geom)
}

/// Fill the new `scene` with one triangle geometry of `n` triangles (none when `n` is 0;
/// see [`triangle_geometry`]) and commit it with the scene's defaults (no scene flags,
/// medium build quality): [`EmbreeScene`]'s scenes.
///
/// # Safety
/// `device` is a live device and `scene` a live scene of it.
unsafe fn commit_triangles(
    device: RTCDevice,
    scene: RTCScene,
    n: usize,
    corners: impl Fn(usize) -> [[f32; 3]; 3],
) -> Result<(), EmbreeError> {
    if n > 0 {
        let geom = triangle_geometry(device, n, corners)?;
        rtcAttachGeometry(scene, geom);
        rtcReleaseGeometry(geom);
        device_error(device, "attaching the triangle geometry")?;
    }
    rtcCommitScene(scene);
    device_error(device, "rtcCommitScene")
}

/// Closest hit for each ray with `rtcIntersect1` on a committed `scene`; `map` turns a
/// hit into hyrt's global triangle index.
fn intersect1_in(scene: RTCScene, rays: &[RayRecord], out: &mut [Option<u32>], map: impl Fn(&RTCHit) -> Option<u32>) {
    intersect1_with(scene, rays, out, |rh| map(&rh.hit));
}

/// [`intersect1_in`] with `map` given the whole ray and hit (the hit's distance in
/// `ray.tfar`), for the hits only.
fn intersect1_with<T>(
    scene: RTCScene,
    rays: &[RayRecord],
    out: &mut [Option<T>],
    map: impl Fn(&RTCRayHit) -> Option<T>,
) {
    let mut ctx = init_context();
    for (o, r) in out.iter_mut().zip(rays) {
        let mut rh = RTCRayHit { ray: EmbreeScene::ray(r), hit: RTCHit::default() };
        rh.hit.geom_id = RTC_INVALID_GEOMETRY_ID;
        rh.hit.inst_id = [RTC_INVALID_GEOMETRY_ID];
        // SAFETY: a committed scene, a valid context and ray/hit.
        unsafe { rtcIntersect1(scene, &mut ctx, &mut rh) };
        *o = if rh.hit.geom_id == RTC_INVALID_GEOMETRY_ID { None } else { map(&rh) };
    }
}

impl EmbreeScene {
    /// Build the scene on a device created with `config` (e.g. `"threads=2"`).
    pub fn new(geometry: &WorldGeometry, config: &str) -> Result<EmbreeScene, EmbreeError> {
        let device = new_device(config)?;
        // SAFETY: a live device; the scene is an empty committed one until `rebuild`.
        let scene = unsafe { rtcNewScene(device) };
        let mut out = EmbreeScene { device, scene, prim_to_triangle: Vec::new(), build_ms: 0.0 };
        device_error(device, "rtcNewScene")?;
        out.rebuild(geometry)?;
        Ok(out)
    }

    /// Replace the scene by a new one of `geometry`'s traceable triangles on the same
    /// device (a full rebuild, as after objects moved): `rtcNewScene`, one triangle
    /// geometry filled and committed, `rtcCommitScene`; `build_ms` times all of it.
    pub fn rebuild(&mut self, geometry: &WorldGeometry) -> Result<(), EmbreeError> {
        // The world records made whole before the clock starts (objects hyrt keeps by
        // reference are made here, not in Embree's time).
        let triangles = geometry.triangles.whole();
        self.prim_to_triangle =
            (0..triangles.len() as u32).filter(|&i| triangle_is_traceable(&triangles[i as usize])).collect();
        let t0 = std::time::Instant::now();
        // SAFETY: plain FFI calls on the device and the handles just created; the old
        // scene is released once, after the new one replaced it.
        unsafe {
            let scene = rtcNewScene(self.device);
            device_error(self.device, "rtcNewScene")?;
            rtcReleaseScene(std::mem::replace(&mut self.scene, scene));
            let prims = &self.prim_to_triangle;
            commit_triangles(self.device, scene, prims.len(), |p| {
                let t = &triangles[prims[p] as usize];
                [t.v0, t.v1, t.v2]
            })?;
        }
        self.build_ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// The linked library's version (`rtcGetDeviceProperty(RTC_DEVICE_PROPERTY_VERSION)`,
    /// e.g. 31305 for 3.13.5).
    pub fn version() -> Result<String, EmbreeError> {
        /// `RTC_DEVICE_PROPERTY_VERSION`.
        const RTC_DEVICE_PROPERTY_VERSION: c_uint = 0;
        // SAFETY: a fresh device, queried and released.
        let v = unsafe {
            let device = rtcNewDevice(c"verbose=0".as_ptr());
            if device.is_null() {
                return Err(EmbreeError("rtcNewDevice returned null".into()));
            }
            let v = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION);
            rtcReleaseDevice(device);
            v
        };
        Ok(format!("{}.{}.{}", v / 10000, v / 100 % 100, v % 100))
    }

    fn ray(r: &RayRecord) -> RTCRay {
        RTCRay {
            org: r.origin,
            tnear: r.t_min,
            dir: r.direction,
            time: 0.0,
            tfar: r.t_max,
            mask: u32::MAX,
            id: 0,
            flags: 0,
        }
    }

    /// Any hit for each ray with `rtcOccluded1`: `out[i]` is true when ray `i` is blocked.
    pub fn occluded1(&self, rays: &[RayRecord], out: &mut [bool]) {
        let mut ctx = init_context();
        for (o, r) in out.iter_mut().zip(rays) {
            let mut ray = Self::ray(r);
            // SAFETY: a committed scene, a valid context and ray.
            unsafe { rtcOccluded1(self.scene, &mut ctx, &mut ray) };
            *o = ray.tfar == f32::NEG_INFINITY;
        }
    }

    fn packet(rays: &[RayRecord]) -> (Valid8, RTCRay8) {
        let mut valid = Valid8([0; 8]);
        let mut p = RTCRay8::default();
        for (i, r) in rays.iter().enumerate().take(PACKET) {
            valid.0[i] = -1;
            p.org_x[i] = r.origin[0];
            p.org_y[i] = r.origin[1];
            p.org_z[i] = r.origin[2];
            p.tnear[i] = r.t_min;
            p.dir_x[i] = r.direction[0];
            p.dir_y[i] = r.direction[1];
            p.dir_z[i] = r.direction[2];
            p.tfar[i] = r.t_max;
            p.mask[i] = u32::MAX;
        }
        (valid, p)
    }

    /// Any hit with 8-wide packets of consecutive rays (`rtcOccluded8`, the default
    /// incoherent context); the last packet may be partial.
    pub fn occluded8(&self, rays: &[RayRecord], out: &mut [bool]) {
        self.occluded8_with(rays, out, false)
    }

    /// [`EmbreeScene::occluded8`] with the context flagged coherent.
    pub fn occluded8_coherent(&self, rays: &[RayRecord], out: &mut [bool]) {
        self.occluded8_with(rays, out, true)
    }

    fn occluded8_with(&self, rays: &[RayRecord], out: &mut [bool], coherent: bool) {
        let mut ctx = context(coherent);
        for (o, r) in out.chunks_mut(PACKET).zip(rays.chunks(PACKET)) {
            let (valid, mut p) = Self::packet(r);
            // SAFETY: 32-byte aligned valid mask and packet, committed scene.
            unsafe { rtcOccluded8(valid.0.as_ptr(), self.scene, &mut ctx, &mut p) };
            for (i, o) in o.iter_mut().enumerate() {
                *o = p.tfar[i] == f32::NEG_INFINITY;
            }
        }
    }

    /// Closest hit for each ray with `rtcIntersect1`: the hyrt global triangle index hit,
    /// or `None`.
    pub fn intersect1(&self, rays: &[RayRecord], out: &mut [Option<u32>]) {
        intersect1_in(self.scene, rays, out, |h| Some(self.prim_to_triangle[h.prim_id as usize]));
    }

    /// Closest hit for each ray with `rtcIntersect1`: the hyrt global triangle index hit and
    /// the hit's ray parameter `t` (the point is `origin + t * direction`), or `None`.
    pub fn intersect1_t(&self, rays: &[RayRecord], out: &mut [Option<(u32, f32)>]) {
        intersect1_with(self.scene, rays, out, |rh| {
            Some((self.prim_to_triangle[rh.hit.prim_id as usize], rh.ray.tfar))
        });
    }

    /// Closest hit with 8-wide packets of consecutive rays (`rtcIntersect8`, the default
    /// incoherent context).
    pub fn intersect8(&self, rays: &[RayRecord], out: &mut [Option<u32>]) {
        self.intersect8_with(rays, out, false)
    }

    /// [`EmbreeScene::intersect8`] with the context flagged coherent.
    pub fn intersect8_coherent(&self, rays: &[RayRecord], out: &mut [Option<u32>]) {
        self.intersect8_with(rays, out, true)
    }

    fn intersect8_with(&self, rays: &[RayRecord], out: &mut [Option<u32>], coherent: bool) {
        let mut ctx = context(coherent);
        for (o, r) in out.chunks_mut(PACKET).zip(rays.chunks(PACKET)) {
            let (valid, ray) = Self::packet(r);
            let mut rh = RTCRayHit8 { ray, hit: RTCHit8::default() };
            rh.hit.geom_id = [RTC_INVALID_GEOMETRY_ID; 8];
            rh.hit.inst_id = [[RTC_INVALID_GEOMETRY_ID; 8]];
            // SAFETY: 32-byte aligned valid mask and packet, committed scene.
            unsafe { rtcIntersect8(valid.0.as_ptr(), self.scene, &mut ctx, &mut rh) };
            for (i, o) in o.iter_mut().enumerate() {
                *o = (rh.hit.geom_id[i] != RTC_INVALID_GEOMETRY_ID)
                    .then(|| self.prim_to_triangle[rh.hit.prim_id[i] as usize]);
            }
        }
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: handles created in `new`, released once.
        unsafe {
            rtcReleaseScene(self.scene);
            rtcReleaseDevice(self.device);
        }
    }
}

/// A two-level Embree scene: each mesh of the moving objects committed once as its own
/// scene in object space, each moving object an instance geometry of its mesh's scene
/// (its transform set with `rtcSetGeometryTransform`), and the static rest (every other
/// object's traceable world triangles) as one triangle geometry of the top scene. The
/// top scene is flagged `RTC_SCENE_FLAG_DYNAMIC` with `RTC_BUILD_QUALITY_LOW`, as Embree
/// advises for scenes committed every frame. A move is [`EmbreeInstances::set_transform`]
/// (`rtcSetGeometryTransform` + `rtcCommitGeometry`) then [`EmbreeInstances::commit`]
/// (`rtcCommitScene` of the top scene).
pub struct EmbreeInstances {
    device: RTCDevice,
    top: RTCScene,
    /// One object-space scene per mesh of a moving object.
    bottoms: Vec<RTCScene>,
    /// Per moving object (in the order given): its id, its instance geometry (held until
    /// drop) and the global index of its first triangle in hyrt's tables.
    instances: Vec<(u32, RTCGeometry, u32)>,
    /// Top-scene `geomID` -> index into `instances` (`u32::MAX` for the static geometry).
    geom_instance: Vec<u32>,
    /// Static geometry `primID` -> hyrt global triangle index.
    static_prims: Vec<u32>,
    /// Milliseconds the first build took (bottom scenes, static geometry, top scene).
    pub build_ms: f64,
}

/// A transform as Embree's `RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR`: glam's columns without
/// their last row.
fn column_major_3x4(m: &Mat4) -> [f32; 12] {
    let c = m.to_cols_array();
    [c[0], c[1], c[2], c[4], c[5], c[6], c[8], c[9], c[10], c[12], c[13], c[14]]
}

impl EmbreeInstances {
    /// Build the two levels of `scene` (whose world tables are `geometry`) with the objects
    /// `moving` as instances, on a device created with `config`.
    pub fn new(
        scene: &Scene,
        geometry: &WorldGeometry,
        moving: &[u32],
        config: &str,
    ) -> Result<EmbreeInstances, EmbreeError> {
        let device = new_device(config)?;
        let t0 = std::time::Instant::now();
        // SAFETY: plain FFI calls on the device and the handles created here; every handle
        // is owned by `out` (released on drop) before the next call that may fail.
        unsafe {
            let top = rtcNewScene(device);
            let mut out = EmbreeInstances {
                device,
                top,
                bottoms: Vec::new(),
                instances: Vec::new(),
                geom_instance: Vec::new(),
                static_prims: Vec::new(),
                build_ms: 0.0,
            };
            device_error(device, "rtcNewScene")?;
            rtcSetSceneFlags(top, RTC_SCENE_FLAG_DYNAMIC);
            rtcSetSceneBuildQuality(top, RTC_BUILD_QUALITY_LOW);
            let is_moving = |o: u32| moving.contains(&o);
            let triangles = geometry.triangles.whole();
            out.static_prims = (0..triangles.len() as u32)
                .filter(|&i| {
                    let t = &triangles[i as usize];
                    !is_moving(t.object) && triangle_is_traceable(t)
                })
                .collect();
            if !out.static_prims.is_empty() {
                let prims = &out.static_prims;
                let geom = triangle_geometry(device, prims.len(), |p| {
                    let t = &triangles[prims[p] as usize];
                    [t.v0, t.v1, t.v2]
                })?;
                let id = rtcAttachGeometry(top, geom);
                rtcReleaseGeometry(geom);
                device_error(device, "attaching the static geometry")?;
                out.set_geom(id, u32::MAX);
            }
            // One object-space scene per mesh, shared by the objects drawing it.
            let mut mesh_scene: Vec<Option<RTCScene>> = vec![None; scene.meshes.len()];
            for &o in moving {
                let object =
                    scene.objects.get(o as usize).ok_or_else(|| EmbreeError(format!("object {o} does not exist")))?;
                let bottom = match mesh_scene[object.mesh] {
                    Some(b) => b,
                    None => {
                        let mesh = &scene.meshes[object.mesh];
                        let b = rtcNewScene(device);
                        out.bottoms.push(b);
                        device_error(device, "rtcNewScene")?;
                        let geom = triangle_geometry(device, mesh.indices.len(), |p| {
                            mesh.indices[p].map(|i| mesh.positions[i as usize].to_array())
                        })?;
                        rtcAttachGeometry(b, geom);
                        rtcReleaseGeometry(geom);
                        rtcCommitScene(b);
                        device_error(device, "building an object-space scene")?;
                        mesh_scene[object.mesh] = Some(b);
                        b
                    }
                };
                let inst = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
                device_error(device, "rtcNewGeometry (instance)")?;
                out.instances.push((o, inst, geometry.objects[o as usize].first_triangle));
                rtcSetGeometryInstancedScene(inst, bottom);
                let id = rtcAttachGeometry(top, inst);
                out.set_geom(id, out.instances.len() as u32 - 1);
                out.set_transform(out.instances.len() - 1, &object.transform);
                device_error(device, "building an instance")?;
            }
            out.commit()?;
            out.build_ms = t0.elapsed().as_secs_f64() * 1e3;
            Ok(out)
        }
    }

    fn set_geom(&mut self, geom_id: u32, instance: u32) {
        let i = geom_id as usize;
        if self.geom_instance.len() <= i {
            self.geom_instance.resize(i + 1, u32::MAX);
        }
        self.geom_instance[i] = instance;
    }

    /// The moving objects' ids, in instance order (the order given to [`EmbreeInstances::new`]).
    pub fn objects(&self) -> impl Iterator<Item = u32> + '_ {
        self.instances.iter().map(|i| i.0)
    }

    /// Set instance `i`'s object-to-world transform (`rtcSetGeometryTransform`, then
    /// `rtcCommitGeometry`); takes effect at the next [`EmbreeInstances::commit`].
    pub fn set_transform(&mut self, i: usize, transform: &Mat4) {
        let xfm = column_major_3x4(transform);
        // SAFETY: a live instance geometry; Embree copies the 12 floats.
        unsafe {
            rtcSetGeometryTransform(self.instances[i].1, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm.as_ptr().cast());
            rtcCommitGeometry(self.instances[i].1);
        }
    }

    /// Commit the top scene (`rtcCommitScene`): Embree rebuilds its top level over the
    /// instances; the object-space scenes are untouched.
    pub fn commit(&mut self) -> Result<(), EmbreeError> {
        // SAFETY: a live scene whose geometries are committed.
        unsafe { rtcCommitScene(self.top) };
        device_error(self.device, "rtcCommitScene (top level)")
    }

    /// Closest hit for each ray with `rtcIntersect1`: the hyrt global triangle index hit
    /// (an instance's `primID` is its mesh's triangle index, offset by the object's first
    /// triangle), or `None`.
    pub fn intersect1(&self, rays: &[RayRecord], out: &mut [Option<u32>]) {
        intersect1_in(self.top, rays, out, |h| {
            let geom = if h.inst_id[0] == RTC_INVALID_GEOMETRY_ID { h.geom_id } else { h.inst_id[0] };
            match *self.geom_instance.get(geom as usize)? {
                u32::MAX => self.static_prims.get(h.prim_id as usize).copied(),
                i => Some(self.instances[i as usize].2 + h.prim_id),
            }
        });
    }
}

impl Drop for EmbreeInstances {
    fn drop(&mut self) {
        // SAFETY: handles created in `new`, released once: the instances, the top scene
        // (which held them), the object-space scenes, then the device.
        unsafe {
            for &(_, g, _) in &self.instances {
                rtcReleaseGeometry(g);
            }
            rtcReleaseScene(self.top);
            for &b in &self.bottoms {
                rtcReleaseScene(b);
            }
            rtcReleaseDevice(self.device);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyrt_core::bvh::{Bvh, BvhPreset};
    use hyrt_core::formats::CameraRecord;
    use hyrt_core::kernels::camera::primary_rays;
    use hyrt_core::scene::Scene;

    #[test]
    fn embree_agrees_with_hyrt_on_the_default_scene() {
        let mut scene = Scene::default_scene();
        scene.ensure_camera_and_lights();
        let g = WorldGeometry::build(&scene);
        let bvh = Bvh::build(&g, BvhPreset::default());
        let e = EmbreeScene::new(&g, "threads=1").unwrap();
        let rec = CameraRecord::new(&scene.camera.unwrap(), 64, 48);
        let rays = primary_rays(&rec);
        let mut h1 = vec![None; rays.len()];
        let mut h8 = vec![None; rays.len()];
        e.intersect1(&rays, &mut h1);
        e.intersect8(&rays, &mut h8);
        let mut h8c = vec![None; rays.len()];
        e.intersect8_coherent(&rays, &mut h8c);
        let hyrt: Vec<Option<u32>> =
            rays.iter().map(|r| bvh.closest_hit(g.traversal_table(), r).map(|h| h.triangle)).collect();
        let mut o1 = vec![false; rays.len()];
        let mut o8 = vec![false; rays.len()];
        e.occluded1(&rays, &mut o1);
        e.occluded8(&rays, &mut o8);
        let mut o8c = vec![false; rays.len()];
        e.occluded8_coherent(&rays, &mut o8c);
        assert!(hyrt.iter().any(Option::is_some) && hyrt.iter().any(Option::is_none));
        // Hit or miss agree on every ray (the default scene has no ray through a shared
        // edge at this size); the 1-wide and 8-wide calls agree exactly.
        let disagree = hyrt.iter().zip(&h1).filter(|(a, b)| a.is_some() != b.is_some()).count();
        assert_eq!(disagree, 0);
        assert_eq!(h1, h8);
        assert_eq!(h1, h8c);
        assert_eq!(o1, o8);
        assert_eq!(o1, o8c);
        assert!(o1.iter().zip(&h1).all(|(o, h)| *o == h.is_some()));
    }

    /// The moving objects' ids: objects named like `parts`, plus `copies` extra objects
    /// sharing the cube's mesh (so that one object-space scene serves several instances).
    fn moving_scene(copies: usize) -> (Scene, Vec<u32>) {
        let mut scene = Scene::default_scene();
        scene.ensure_camera_and_lights();
        let cube = scene.objects.iter().position(|o| o.name.contains("cube")).unwrap();
        let mut moving: Vec<u32> = vec![cube as u32];
        moving.extend(scene.objects.iter().filter(|o| o.name.contains("torus")).map(|o| o.id));
        for i in 0..copies {
            let mut o = scene.objects[cube].clone();
            o.id = scene.objects.len() as u32;
            o.transform = Mat4::from_translation(hyrt_core::glam::Vec3::new(-1.0 - i as f32, 0.0, 1.5)) * o.transform;
            moving.push(o.id);
            scene.objects.push(o);
        }
        (scene, moving)
    }

    /// Embree's two-level scene answers primary rays as hyrt's two-level scene, before and
    /// after the objects move (the same triangle, in hyrt's global numbering, on every ray
    /// at this size), and its full rebuild agrees but for a ray or two.
    #[test]
    fn embree_instances_agree_with_hyrts_two_levels_as_objects_move() {
        use crate::bench::moving::frame_transform;
        for copies in [0, 3] {
            let (mut scene, moving) = moving_scene(copies);
            let g = WorldGeometry::build(&scene);
            let mut prepared = hyrt_cpu::bvh_build::prepare_moving(&scene, BvhPreset::default(), &moving);
            assert!(prepared.levels.is_some());
            let mut e = EmbreeInstances::new(&scene, &g, &moving, "threads=1").unwrap();
            let mut flat = EmbreeScene::new(&g, "threads=1").unwrap();
            assert_eq!(e.objects().collect::<Vec<_>>(), moving);
            let rec = CameraRecord::new(&scene.camera.unwrap(), 64, 48);
            let rays = primary_rays(&rec);
            let rests: Vec<Mat4> = moving.iter().map(|&o| scene.objects[o as usize].transform).collect();
            for frame in [0, 5, 20] {
                for (i, (&o, rest)) in moving.iter().zip(&rests).enumerate() {
                    scene.objects[o as usize].transform = frame_transform(*rest, frame, 0.05);
                    e.set_transform(i, &scene.objects[o as usize].transform);
                }
                e.commit().unwrap();
                prepared.move_objects(&scene, &moving).unwrap();
                flat.rebuild(&prepared.geometry).unwrap();
                let levels = prepared.levels.as_ref().unwrap();
                let g = &prepared.geometry;
                let hyrt: Vec<Option<u32>> = rays.iter().map(|r| levels.closest_hit(r).map(|h| h.triangle)).collect();
                let mut embree = vec![None; rays.len()];
                e.intersect1(&rays, &mut embree);
                let moving_hits =
                    hyrt.iter().flatten().filter(|&&h| moving.contains(&g.triangle(h as usize).object)).count();
                assert!(moving_hits > 20, "frame {frame}, {copies} copies: {moving_hits} rays on the moving objects");
                assert_eq!(hyrt, embree, "frame {frame}, {copies} copies");
                // The flat rebuild in world space: a ray on a shared edge or on two touching
                // objects may land on another triangle (Embree's test is not watertight).
                flat.intersect1(&rays, &mut embree);
                let differ: Vec<usize> = (0..rays.len()).filter(|&i| hyrt[i] != embree[i]).collect();
                assert!(differ.len() <= 2, "frame {frame}, {copies} copies, flat: rays {differ:?} differ");
            }
        }
    }

    #[test]
    fn transforms_go_to_embree_column_major_without_the_last_row() {
        let m = Mat4::from_cols_array(&[1., 2., 3., 0., 4., 5., 6., 0., 7., 8., 9., 0., 10., 11., 12., 1.]);
        assert_eq!(column_major_3x4(&m), [1., 2., 3., 4., 5., 6., 7., 8., 9., 10., 11., 12.]);
    }
}
