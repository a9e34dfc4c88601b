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
/// medium build quality): [`EmbreeScene`]'s scenes, and [`EmbreeBuild::detect`]'s probe.
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

/// Embree 3's ISA namespaces, lowest first (`avx512` is 3.13's name for AVX-512 on Skylake
/// and later; earlier releases named it `avx512skx`, and `avx512knl` for Knights Landing).
pub const EMBREE_ISAS: [&str; 7] = ["sse2", "sse42", "avx", "avx2", "avx512knl", "avx512skx", "avx512"];

/// What Embree runs on this machine, as its verbose output says: the ISA its run-time
/// dispatch selected and the acceleration structure it builds for a triangle scene of
/// [`EmbreeScene`]'s kind (default scene flags and build quality).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EmbreeBuild {
    /// The ISA of the traversal kernels selected for the scene: the highest namespace of
    /// the selected intersectors (`avx2` in `intersector1  = avx2::BVH8Triangle4Intersector1Moeller`;
    /// an SSE4.2 dispatch keeps SSE2's single-ray kernel, `sse2::`, beside `sse42::` packets).
    pub isa: String,
    /// The acceleration structure built (`BVH8<triangle4>` in `building BVH8<triangle4> using
    /// avx::BVH8BuilderSAH ...`).
    pub bvh: String,
    /// Its branching factor (8 for `BVH8<...>`).
    pub width: u32,
}

impl std::fmt::Display for EmbreeBuild {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ISA {} selected at run time, {} ({}-wide) for triangle scenes", self.isa, self.bvh, self.width)
    }
}

impl EmbreeBuild {
    /// Ask Embree on this machine: a device created with `verbose=2` commits a scene of a
    /// few triangles as [`EmbreeScene`] commits its scenes, and what Embree prints while
    /// doing so (to file descriptor 1, captured by [`capture_stdout`]) is [`EmbreeBuild::parse`]d.
    pub fn detect() -> Result<EmbreeBuild, EmbreeError> {
        /// A row of small triangles, so that the builder has more than one primitive.
        const TRIANGLES: usize = 8;
        let (built, text) = capture_stdout(|| {
            let device = new_device("verbose=2")?;
            // SAFETY: a fresh device and scene, released before returning.
            unsafe {
                let scene = rtcNewScene(device);
                let built = device_error(device, "rtcNewScene").and_then(|()| {
                    commit_triangles(device, scene, TRIANGLES, |p| {
                        let x = p as f32;
                        [[x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x, 1.0, 0.0]]
                    })
                });
                rtcReleaseScene(scene);
                rtcReleaseDevice(device);
                built
            }
        })?;
        built?;
        EmbreeBuild::parse(&text)
    }

    /// The selected ISA and the BVH built, from Embree 3's verbose output (`verbose=2`):
    /// the `selected scene intersector` block and the `building ... using ...` line.
    /// Errors when either is missing, when the selected intersectors' ISAs cannot be ranked
    /// ([`EMBREE_ISAS`]), or when more than one BVH was built.
    pub fn parse(text: &str) -> Result<EmbreeBuild, EmbreeError> {
        let not_found = |what: &str| EmbreeError(format!("{what} not found in Embree's verbose output"));
        let mut lines = text.lines().map(str::trim);
        lines
            .by_ref()
            .find(|l| *l == "selected scene intersector")
            .ok_or_else(|| not_found("the \"selected scene intersector\" block"))?;
        // `intersector1  = avx2::BVH8Triangle4Intersector1Moeller`, one line per width.
        let mut isas: Vec<&str> = Vec::new();
        for l in lines.map_while(|l| l.strip_prefix("intersector")) {
            let isa = l.split_once('=').and_then(|(_, k)| k.trim().split_once("::")).map(|(isa, _)| isa);
            match isa {
                Some(isa) if !isa.is_empty() && isa.bytes().all(|b| b.is_ascii_alphanumeric()) => isas.push(isa),
                _ => return Err(EmbreeError(format!("unexpected intersector line \"intersector{l}\""))),
            }
        }
        isas.sort_unstable();
        isas.dedup();
        if isas.is_empty() {
            return Err(not_found("a selected intersector"));
        }
        let rank = |isa: &str| EMBREE_ISAS.iter().position(|&k| k == isa);
        let highest = match isas[..] {
            [isa] => Some(isa),
            _ => isas
                .iter()
                .map(|&i| rank(i))
                .collect::<Option<Vec<_>>>()
                .and_then(|r| r.into_iter().max())
                .map(|r| EMBREE_ISAS[r]),
        };
        let isa = highest
            .ok_or_else(|| EmbreeError(format!("cannot rank the selected intersectors' ISAs {isas:?}")))?
            .to_string();
        // `building BVH8<triangle4> using avx::BVH8BuilderSAH ...`
        let mut bvhs: Vec<&str> = text
            .lines()
            .filter_map(|l| l.trim().strip_prefix("building ")?.split_once(" using ").map(|(bvh, _)| bvh))
            .collect();
        bvhs.dedup();
        let bvh = match bvhs[..] {
            [bvh] => bvh.to_string(),
            [] => return Err(not_found("a \"building BVH... using ...\" line")),
            _ => return Err(EmbreeError(format!("more than one BVH built: {bvhs:?}"))),
        };
        let width = bvh
            .strip_prefix("BVH")
            .and_then(|r| r.split_once('<'))
            .filter(|(_, leaf)| leaf.len() > 1 && leaf.ends_with('>'))
            .and_then(|(w, _)| w.parse().ok())
            .ok_or_else(|| EmbreeError(format!("unexpected BVH name {bvh:?} (not BVH<width><<leaf>>)")))?;
        Ok(EmbreeBuild { isa, bvh, width })
    }
}

extern "C" {
    fn dup2(old: c_int, new: c_int) -> c_int;
    /// `fflush(NULL)` flushes every C output stream (C++'s `std::cout` writes through C's
    /// `stdout` while synchronised with stdio, the default).
    fn fflush(stream: *mut c_void) -> c_int;
}

/// Run `f` with file descriptor 1 redirected into a pipe, and return its result and what
/// was written to the descriptor meanwhile (Embree prints its verbose output to C++'s
/// `std::cout`). Rust's stdout stays locked throughout, so this process's own `print!`s
/// wait rather than end up in the capture; writes to the descriptor by other means (C
/// code on other threads) would.
fn capture_stdout<T>(f: impl FnOnce() -> T) -> Result<(T, String), EmbreeError> {
    use std::io::{Read, Write};
    use std::os::fd::{AsFd, AsRawFd};
    let failed = |what: &str, e: std::io::Error| EmbreeError(format!("capturing Embree's output: {what}: {e}"));
    let mut stdout = std::io::stdout().lock();
    stdout.flush().map_err(|e| failed("flushing stdout", e))?;
    let saved = stdout.as_fd().try_clone_to_owned().map_err(|e| failed("duplicating stdout", e))?;
    let (mut reader, writer) = std::io::pipe().map_err(|e| failed("creating a pipe", e))?;
    // The pipe is drained while `f` writes, so that a long output cannot block it.
    let drain = std::thread::Builder::new()
        .name("embree-stdout".into())
        .spawn(move || {
            let mut text = Vec::new();
            reader.read_to_end(&mut text).map(|_| text)
        })
        .map_err(|e| failed("starting the reader thread", e))?;
    let redirect = |from: c_int, what: &str| {
        // SAFETY: flushing C's streams, then replacing descriptor 1 by a descriptor open here.
        unsafe {
            fflush(std::ptr::null_mut());
            if dup2(from, stdout.as_fd().as_raw_fd()) < 0 {
                return Err(failed(what, std::io::Error::last_os_error()));
            }
        }
        Ok(())
    };
    redirect(writer.as_raw_fd(), "redirecting stdout into the pipe")?;
    // Descriptor 1 now holds the pipe's only write end: the reader sees the end of the
    // output when it is restored.
    drop(writer);
    let out = f();
    redirect(saved.as_raw_fd(), "restoring stdout")?;
    let text = drain.join().map_err(|_| EmbreeError("the reader thread panicked".into()))?;
    let text = text.map_err(|e| failed("reading the pipe", e))?;
    Ok((out, String::from_utf8_lossy(&text).into_owned()))
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
    use hyrt_core::kernels::ray::intersect_triangle_watertight;
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

    /// Relative depth difference of two faces that coincide in exact arithmetic (touching
    /// copies of one cube), their vertices placed by different transforms: a few f32 ulps.
    const COINCIDENT_FACES: f32 = 4.0 * f32::EPSILON;

    /// Embree's two-level scene answers primary rays as hyrt's two-level scene, before and
    /// after the objects move (the same triangle, in hyrt's global numbering, on every ray
    /// at this size but where two copies touch and the ray meets two coincident faces), and
    /// its full rebuild agrees but for a ray or two.
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
                // Where the answers differ, the copies touch (from frame 20 with 3 copies):
                // the ray meets two coincident faces, hyrt's and Embree's triangles at the
                // same depth but for rounding (their world positions round differently), and
                // either tracer may take either one.
                for i in (0..rays.len()).filter(|&i| hyrt[i] != embree[i]) {
                    let r = &rays[i];
                    let depth = |h: Option<u32>| {
                        let t = g.triangle(h? as usize);
                        let (o, d) = (r.origin.into(), r.direction.into());
                        intersect_triangle_watertight(o, d, 0.0, f32::INFINITY, t.v0.into(), t.v1.into(), t.v2.into())
                            .map(|h| h.t)
                    };
                    let (a, b) = (depth(hyrt[i]), depth(embree[i]));
                    let coincident = a.zip(b).is_some_and(|(a, b)| (a - b).abs() <= COINCIDENT_FACES * a);
                    assert!(
                        coincident,
                        "frame {frame}, {copies} copies: ray {i} hits {:?} at {a:?} (hyrt), {:?} at {b:?} (Embree)",
                        hyrt[i], embree[i]
                    );
                }
                // The flat rebuild in world space: a ray on a shared edge or on two touching
                // objects may land on another triangle (Embree's test is not watertight).
                flat.intersect1(&rays, &mut embree);
                let differ: Vec<usize> = (0..rays.len()).filter(|&i| hyrt[i] != embree[i]).collect();
                assert!(differ.len() <= 2, "frame {frame}, {copies} copies, flat: rays {differ:?} differ");
            }
        }
    }

    /// Lines Embree 3.13.5 printed with `verbose=2` on an AVX2 machine (Debian's build) for
    /// a device, then a committed scene of one triangle (`rtcCommitScene`), the rest elided
    /// (and trailing spaces).
    const VERBOSE_3_13_5: &str = "
Embree Ray Tracing Kernels 3.13.5 ()
   Targets  : SSE SSE2 SSE3 SSSE3 SSE4.1 SSE4.2 AVX AVXI AVX2
    Targets : SSE SSE2 SSE3 SSSE3 SSE4.1 SSE4.2 AVX AVXI AVX2  (supported)
              SSE2 SSE4.2 AVX AVX2 AVX512  (compile time enabled)
              triangles:          1
building BVH8<triangle4> using avx::BVH8BuilderSAH ...
finished BVH8<triangle4> : 0.115156ms, 0.00868386 Mprim/s, 0.00152836 GB/s
  primitives = 1, vertices = 0, depth = 0
created scene intersector
  accels[0]
    intersector1  = avx2::BVH8Triangle4Intersector1Moeller
    intersector4  = avx2::BVH8Triangle4Intersector4HybridMoellerNoFilter
    intersector8  = avx2::BVH8Triangle4Intersector8HybridMoellerNoFilter
    intersectorN = avx2::BVH8Triangle4IntersectorStreamMoellerNoFilter
selected scene intersector
  intersector1  = avx2::BVH8Triangle4Intersector1Moeller
  intersector4  = avx2::BVH8Triangle4Intersector4HybridMoellerNoFilter
  intersector8  = avx2::BVH8Triangle4Intersector8HybridMoellerNoFilter
  intersectorN = avx2::BVH8Triangle4IntersectorStreamMoellerNoFilter
";

    /// The same with `verbose=2,isa=sse4.2` (the created-intersector block elided too, as
    /// it repeats the selected one): SSE4.2's dispatch keeps SSE2's single-ray kernel.
    const VERBOSE_3_13_5_SSE42: &str = "
Embree Ray Tracing Kernels 3.13.5 ()
    Targets : SSE SSE2 SSE3 SSSE3 SSE4.1 SSE4.2  (supported)
              SSE2 SSE4.2 AVX AVX2 AVX512  (compile time enabled)
building BVH4<triangle4> using sse2::BVH4BuilderSAH ...
finished BVH4<triangle4> : 0.0469685ms, 0.0212909 Mprim/s, 0.0037472 GB/s
selected scene intersector
  intersector1  = sse2::BVH4Triangle4Intersector1Moeller
  intersector4  = sse42::BVH4Triangle4Intersector4HybridMoellerNoFilter
  intersectorN = sse42::BVH4Triangle4IntersectorStreamMoellerNoFilter
";

    #[test]
    fn the_isa_and_the_bvh_come_from_embrees_verbose_output() {
        let b = EmbreeBuild::parse(VERBOSE_3_13_5).unwrap();
        assert_eq!(b, EmbreeBuild { isa: "avx2".into(), bvh: "BVH8<triangle4>".into(), width: 8 });
        assert_eq!(b.to_string(), "ISA avx2 selected at run time, BVH8<triangle4> (8-wide) for triangle scenes");
        // The highest of the selected intersectors' ISAs, not the builder's nor the first.
        let b = EmbreeBuild::parse(VERBOSE_3_13_5_SSE42).unwrap();
        assert_eq!((b.isa.as_str(), b.bvh.as_str(), b.width), ("sse42", "BVH4<triangle4>", 4));
        let b = EmbreeBuild::parse(&VERBOSE_3_13_5.replace("  intersector4  = avx2", "  intersector4  = sse42"));
        assert_eq!(b.unwrap().isa, "avx2");
    }

    #[test]
    fn verbose_output_without_the_isa_or_the_bvh_is_an_error() {
        let without = |drop: &dyn Fn(&str) -> bool| {
            let text: Vec<&str> = VERBOSE_3_13_5.lines().filter(|l| !drop(l)).collect();
            EmbreeBuild::parse(&text.join("\n")).unwrap_err().to_string()
        };
        // `verbose=1` prints the device's header only.
        let e = EmbreeBuild::parse(&VERBOSE_3_13_5[..VERBOSE_3_13_5.find("building").unwrap()]).unwrap_err();
        assert!(e.to_string().contains("selected scene intersector"), "{e}");
        assert!(without(&|l| l.starts_with("selected")).contains("\"selected scene intersector\" block not found"));
        // The block without its lines: the ISA of the created (not selected) ones is not taken.
        let e = without(&|l| l.starts_with("  intersector"));
        assert!(e.contains("a selected intersector not found"), "{e}");
        assert!(without(&|l| l.starts_with("building")).contains("\"building BVH... using ...\" line not found"));
        let e = EmbreeBuild::parse(&VERBOSE_3_13_5.replace("  intersector8  = avx2", "  intersector8  = avx10"));
        assert!(e
            .unwrap_err()
            .to_string()
            .contains("cannot rank the selected intersectors' ISAs [\"avx10\", \"avx2\"]"));
        let e = EmbreeBuild::parse(&VERBOSE_3_13_5.replace("  intersector4  = avx2::", "  intersector4  = "));
        assert!(e.unwrap_err().to_string().contains("unexpected intersector line"));
        for bvh in ["BVH<triangle4>", "BVH8<>", "BVHx<triangle4>", "BVH8 triangle4"] {
            let e = EmbreeBuild::parse(&VERBOSE_3_13_5.replace("building BVH8<triangle4>", &format!("building {bvh}")));
            assert!(e.unwrap_err().to_string().contains("unexpected BVH name"), "{bvh}");
        }
        let two =
            VERBOSE_3_13_5.replace("finished", "building BVH4<triangle4v> using sse2::BVH4BuilderSAH ...\nfinished");
        assert!(EmbreeBuild::parse(&two).unwrap_err().to_string().contains("more than one BVH"));
    }

    /// Embree on this machine: a known ISA, at least AVX2 where the CPU has what Embree's
    /// AVX2 kernels need (its `AVX2` target: AVX, F16C, RDRAND, AVX2, FMA3, BMI1, BMI2,
    /// LZCNT), so that the peer does not run its SSE path, and a 4- or 8-wide BVH.
    #[test]
    fn embree_on_this_machine_selects_a_known_isa_and_builds_a_4_or_8_wide_bvh() {
        let b = EmbreeBuild::detect().unwrap();
        assert!(EMBREE_ISAS.contains(&b.isa.as_str()), "{b:?}");
        assert!(b.width == 4 || b.width == 8, "{b:?}");
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            if has!("avx")
                && has!("f16c")
                && has!("rdrand")
                && has!("avx2")
                && has!("fma")
                && has!("bmi1")
                && has!("bmi2")
                && has!("lzcnt")
            {
                assert!(b.isa == "avx2" || b.isa.starts_with("avx512"), "{b:?}");
            }
        }
        println!("Embree here: {b}");
        assert_eq!(EmbreeBuild::detect().unwrap(), b, "a second probe");
    }

    #[test]
    fn capture_stdout_takes_what_c_prints_and_restores_the_descriptor() {
        use std::os::fd::AsFd;
        use std::os::unix::fs::MetadataExt;
        extern "C" {
            fn puts(s: *const c_char) -> c_int;
        }
        let stdout_file = || {
            let f = std::fs::File::from(std::io::stdout().as_fd().try_clone_to_owned().unwrap());
            let m = f.metadata().unwrap();
            (m.dev(), m.ino())
        };
        let before = stdout_file();
        // SAFETY: a NUL-terminated string; `puts` buffers it in C's `stdout`.
        let (written, text) = capture_stdout(|| unsafe { puts(c"printed by C".as_ptr()) }).unwrap();
        assert!(written >= 0);
        assert_eq!(text, "printed by C\n");
        assert_eq!(stdout_file(), before, "descriptor 1 is the same file again");
    }

    #[test]
    fn transforms_go_to_embree_column_major_without_the_last_row() {
        let m = Mat4::from_cols_array(&[1., 2., 3., 0., 4., 5., 6., 0., 7., 8., 9., 0., 10., 11., 12., 1.]);
        assert_eq!(column_major_3x4(&m), [1., 2., 3., 4., 5., 6., 7., 8., 9., 10., 11., 12.]);
    }
}
