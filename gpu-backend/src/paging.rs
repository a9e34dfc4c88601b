//! Scene tables larger than one storage binding, split into pages (issue 40).
//!
//! A device binds at most `max_storage_buffer_binding_size` bytes of a buffer at once
//! (lavapipe: 128 MiB, 2.8 million world records). The scene tables that grow with the
//! triangle count, with the object count or with the textures are uploaded in pages, each
//! page a buffer and a binding of its own: the record tables in pages of `1 << shift`
//! records, the per-object tables in pages of `1 << object_shift` records, the word tables
//! in pages of `1 << word_shift` words:
//!
//! | index space | tables ([`Table`]) | record bytes | page |
//! |---|---|---:|---|
//! | stored world record | `triangles`, `normals` | 48, 36 | `1 << shift` records |
//! | BVH leaf slot | `bvh_leaf_triangles`, `bvh_prim_indices` | 48, 4 | `1 << shift` records |
//! | BVH node | `bvh_nodes` | 32 | `1 << shift` records |
//! | object | `placements` (objects by reference), `objects` | 112, 64 | `1 << object_shift` records |
//! | instance | `instances` (two levels) | 64 | `1 << object_shift` records |
//! | light | `lights` (the frame's lights, then the emitter table: [`crate::buffers::SceneBuffers::lights`]) | 96 | `1 << object_shift` records |
//! | shared mesh word | `mesh_words` | 4 | `1 << word_shift` words |
//! | surface table word | `surface` (materials, texture coordinates, vertex colours, tangents, textures: [`crate::texture::SurfaceBuffers`]) | 4 | `1 << word_shift` words |
//!
//! The shared meshes' words of objects by reference (`mesh_words`) are paged as the surface
//! tables are. The lights' pages are the only ones `compaction` and `shadow_denoise` read
//! ([`TablePages::lights_only`]): those stages are compiled for them when a scene's
//! emitters outgrow one binding (1.4 million emissive triangles on lavapipe), and again
//! when a deformed emitter changes the table's length across a page.
//!
//! `shift` is the device's ([`page_shift`]): the largest with a page of the largest record
//! (48 bytes) within one binding; `object_shift` ([`object_page_shift`]) the largest with a
//! page of the largest per-object or light record (a 112-byte placement) within one binding
//! (lavapipe: 20, 1,048,576 objects); `word_shift` ([`word_page_shift`]) the largest with a
//! page of words within one binding (lavapipe: 25, a whole 128 MiB binding, where pages of
//! `1 << shift` words would hold 8 MiB). A scene whose tables each fit one page is uploaded and
//! compiled as before ([`TablePages::default`]): its shaders are the same text. Otherwise
//! the stages that read a paged table are compiled for its page count ([`TablePages`], part
//! of the scene's [`crate::texture::Specialization`]): [`paged_source`] declares the further
//! pages in the table's group at [`page_binding`] and rewrites every `table[i]` of the
//! source into `table_at(i)` (`surface_word(i)` for the surface tables, whose stages
//! define a `surface_at` of their own), whose switch reads page `i >> shift` at `i & mask`,
//! and every `arrayLength(&table)` into the records of the full pages plus the last page's
//! `arrayLength` (each page is uploaded at its records' size: the placements' binary search
//! of `shaders/world_triangles.wgsl`). Those are
//! the same records the unpaged table holds at `i`, so frames are the same bits; what a
//! device can hold is bounded by its memory, not by one binding.
//!
//! Each further page is one more storage buffer bound per stage: a stage that reads every
//! paged table (`bounce_trace`) binds `(pages - 1)` more for each, within the adapter's
//! `max_storage_buffers_per_shader_stage` (lavapipe: 32), which
//! [`crate::backend::GpuBackend`] checks before a frame. The surface tables are read at
//! many places of the largest stages (texels, materials, alpha tests, normal maps in the
//! bounce stages): their accessor reads every page and selects one, without a branch; with
//! a switch (or ifs) at each read, lavapipe crashed (a SIGSEGV in its command thread) on
//! the bounce stages of textured cases at three pages.

/// The most pages of one table.
pub const MAX_PAGES: u32 = 16;

/// Bytes of the largest record of a paged table (a `TriangleRecord`): a page of any
/// record table fits one binding.
const LARGEST_RECORD_BYTES: u64 = 48;

/// Bytes of the largest record of a per-object table (a `PlacementRecord`): a page of
/// placements, objects or instances fits one binding.
const LARGEST_OBJECT_RECORD_BYTES: u64 = 112;

/// Bytes of a word of the surface tables.
const WORD_BYTES: u64 = 4;

/// The first binding of the further pages: page `k` (from 1) of table `t` is at
/// [`page_binding`]`(t, k)`, in the group that declares the table's first page. Above
/// every binding the stages declare.
pub const PAGE_BINDING: u32 = 64;

/// A paged table, as the stages name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Table {
    /// `array<TriangleRecord>`: the stored world records.
    Triangles,
    /// `array<f32>`: nine per stored world record.
    Normals,
    /// `array<TriangleRecord>`: the BVH's triangles in leaf-slot order.
    LeafTriangles,
    /// `array<u32>`: the global (or mesh-local) index of each leaf slot.
    PrimIndices,
    /// `array<BvhNode>`.
    Nodes,
    /// `array<u32>`: the surface tables, packed ([`hyrt_core::geometry::SurfaceTables::packed`]).
    Surface,
    /// `array<u32>`: every shared mesh's positions, normals and triangles, once, for the
    /// objects by reference ([`hyrt_core::geometry::WorldTriangles::mesh_words`]).
    MeshWords,
    /// `array<PlacementRecord>`: one per object, with objects by reference.
    Placements,
    /// `array<ObjectRecord>`: one per object.
    Objects,
    /// `array<InstanceRecord>`: a two-level scene's instances.
    Instances,
    /// `array<LightRecord>`: the frame's lights, then the emitter table
    /// ([`crate::buffers::SceneBuffers::lights`]).
    Lights,
}

impl Table {
    pub const ALL: [Table; 11] = [
        Table::Triangles,
        Table::Normals,
        Table::LeafTriangles,
        Table::PrimIndices,
        Table::Nodes,
        Table::Surface,
        Table::MeshWords,
        Table::Placements,
        Table::Objects,
        Table::Instances,
        Table::Lights,
    ];

    /// The name of the table's (first page's) binding in the WGSL.
    pub fn name(self) -> &'static str {
        match self {
            Table::Triangles => "triangles",
            Table::Normals => "normals",
            Table::LeafTriangles => "bvh_leaf_triangles",
            Table::PrimIndices => "bvh_prim_indices",
            Table::Nodes => "bvh_nodes",
            Table::Surface => "surface",
            Table::MeshWords => "mesh_words",
            Table::Placements => "placements",
            Table::Objects => "objects",
            Table::Instances => "instances",
            Table::Lights => "lights",
        }
    }

    /// The name of the accessor [`paged_source`] defines: `NAME_at`, but `surface_word` for
    /// the surface tables (the stages that read them define `surface_at`: the surface
    /// record at a hit).
    pub fn accessor(self) -> String {
        match self {
            Table::Surface => "surface_word".to_string(),
            _ => format!("{}_at", self.name()),
        }
    }

    /// Whether the table is of words, paged by [`TablePages::word_shift`].
    pub fn is_words(self) -> bool {
        matches!(self, Table::Surface | Table::MeshWords)
    }

    /// Whether the table is of per-object records, paged by [`TablePages::object_shift`].
    pub fn is_per_object(self) -> bool {
        matches!(self, Table::Placements | Table::Objects | Table::Instances | Table::Lights)
    }

    /// Bytes of one record: what one index of its index space takes (nine floats for the
    /// normals of one world record).
    pub fn record_bytes(self) -> u64 {
        match self {
            Table::Triangles | Table::LeafTriangles => 48,
            Table::Normals => 36,
            Table::PrimIndices | Table::Surface | Table::MeshWords => 4,
            Table::Nodes => 32,
            Table::Placements => 112,
            Table::Objects | Table::Instances => 64,
            Table::Lights => 96,
        }
    }

    /// Array elements per record (the normals' nine floats; one for the others).
    fn elements_per_record(self) -> u32 {
        match self {
            Table::Normals => 9,
            _ => 1,
        }
    }

    fn index(self) -> u32 {
        Table::ALL.iter().position(|&t| t == self).unwrap() as u32
    }
}

/// Where page `k` (1 to [`MAX_PAGES`] - 1) of `table` is bound.
pub fn page_binding(table: Table, k: u32) -> u32 {
    debug_assert!((1..MAX_PAGES).contains(&k));
    PAGE_BINDING + table.index() * MAX_PAGES + k
}

/// The nodes and leaf slots of `scene`'s BVH as the device holds it: both levels packed
/// ([`hyrt_core::bvh::two_level::PackedLevels`]), or the one tree.
pub fn bvh_counts(scene: &hyrt_core::frame::PreparedScene) -> (usize, usize) {
    match &scene.levels {
        Some(l) => (
            l.top.len() + l.bottoms.iter().map(|b| b.nodes.len()).sum::<usize>(),
            l.bottoms.iter().map(|b| b.leaf_triangles.len()).sum::<usize>(),
        ),
        None => (scene.bvh.nodes.len(), scene.bvh.leaf_triangles.len()),
    }
}

/// log2 of the records of `record_bytes` bytes per page on a device with `limits`: the
/// largest with a page within one storage binding (and one buffer).
fn shift_for(limits: &wgpu::Limits, record_bytes: u64) -> u32 {
    let binding = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    (binding / record_bytes).max(1).ilog2().min(31)
}

/// log2 of the records per page on a device with `limits`: the largest with a page of
/// 48-byte records within one storage binding (and one buffer). Lavapipe's 128 MiB: 21
/// (2,097,152 records, 96 MiB).
pub fn page_shift(limits: &wgpu::Limits) -> u32 {
    shift_for(limits, LARGEST_RECORD_BYTES)
}

/// log2 of the words per page of the surface tables on a device with `limits`: the largest
/// with a page of words within one storage binding (and one buffer). Lavapipe's 128 MiB:
/// 25 (33,554,432 words).
pub fn word_page_shift(limits: &wgpu::Limits) -> u32 {
    shift_for(limits, WORD_BYTES)
}

/// log2 of the records per page of the per-object tables (placements, objects, instances)
/// on a device with `limits`: the largest with a page of 112-byte placements within one
/// storage binding (and one buffer). Lavapipe's 128 MiB: 20 (1,048,576 objects, 112 MiB).
pub fn object_page_shift(limits: &wgpu::Limits) -> u32 {
    shift_for(limits, LARGEST_OBJECT_RECORD_BYTES)
}

/// The pages of tables of `counts` records in pages of `1 << shift`: `None` past
/// [`MAX_PAGES`], `Some(None)` where each fits one page (nothing paged).
fn page_counts<const N: usize>(counts: [u64; N], shift: u32) -> Option<Option<[u8; N]>> {
    let pages = counts.map(|n| n.div_ceil(1 << shift).max(1));
    match pages.iter().copied().max().unwrap_or(1) {
        1 => Some(None),
        n if n > MAX_PAGES as u64 => None,
        _ => Some(Some(pages.map(|p| p as u8))),
    }
}

/// How a scene's paged tables are split: the page shifts and each index space's page
/// count. The default (every count 0) is a scene whose tables fit one page each: nothing
/// paged, the shaders as written. The record tables and the word tables are paged
/// independently: either may be paged while the other is not.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct TablePages {
    /// log2 of the records per page ([`page_shift`]); 0 when nothing is paged.
    pub shift: u8,
    /// Pages of the stored world records (and their normals).
    pub triangles: u8,
    /// Pages of the BVH's leaf slots.
    pub slots: u8,
    /// Pages of the BVH's nodes.
    pub nodes: u8,
    /// log2 of the words per page of the surface tables ([`word_page_shift`]); 0 when
    /// they are not paged.
    pub word_shift: u8,
    /// Pages of the surface tables' words.
    pub surface: u8,
    /// Pages of the shared meshes' words (objects by reference).
    pub mesh_words: u8,
    /// log2 of the records per page of the per-object tables ([`object_page_shift`]); 0
    /// when none is paged.
    pub object_shift: u8,
    /// Pages of the placements (objects by reference).
    pub placements: u8,
    /// Pages of the object records.
    pub objects: u8,
    /// Pages of the instances (two levels).
    pub instances: u8,
    /// Pages of the lights and the emitter table after them.
    pub lights: u8,
}

impl TablePages {
    /// Nothing paged: every table in one binding ([`TablePages::default`], usable in
    /// constants).
    pub const UNPAGED: TablePages = TablePages {
        shift: 0,
        triangles: 0,
        slots: 0,
        nodes: 0,
        word_shift: 0,
        surface: 0,
        mesh_words: 0,
        object_shift: 0,
        placements: 0,
        objects: 0,
        instances: 0,
        lights: 0,
    };

    /// The pages of tables of `triangles` stored records, `slots` leaf slots and `nodes`
    /// nodes with `1 << shift` records a page (no word table paged); `None` past
    /// [`MAX_PAGES`] pages.
    pub fn of_counts(triangles: u64, slots: u64, nodes: u64, shift: u32) -> Option<TablePages> {
        Some(match page_counts([triangles, slots, nodes], shift)? {
            None => TablePages::default(),
            Some([t, s, n]) => TablePages { shift: shift as u8, triangles: t, slots: s, nodes: n, ..Self::default() },
        })
    }

    /// `self` with surface tables of `surface` words and shared meshes of `mesh` words in
    /// pages of `1 << word_shift` words; `None` past [`MAX_PAGES`] pages.
    pub fn with_words(self, surface: u64, mesh: u64, word_shift: u32) -> Option<TablePages> {
        Some(match page_counts([surface, mesh], word_shift)? {
            None => TablePages { word_shift: 0, surface: 0, mesh_words: 0, ..self },
            Some([s, m]) => TablePages { word_shift: word_shift as u8, surface: s, mesh_words: m, ..self },
        })
    }

    /// `self` with the per-object tables of `counts` records (`[placements, objects,
    /// instances, lights]`, the lights with the emitter table) in pages of
    /// `1 << object_shift` records; `None` past [`MAX_PAGES`] pages.
    pub fn with_objects(self, counts: [u64; 4], object_shift: u32) -> Option<TablePages> {
        Some(match page_counts(counts, object_shift)? {
            None => TablePages { object_shift: 0, placements: 0, objects: 0, instances: 0, lights: 0, ..self },
            Some([placements, objects, instances, lights]) => {
                TablePages { object_shift: object_shift as u8, placements, objects, instances, lights, ..self }
            }
        })
    }

    /// `self`'s lights' pages alone: what the stages that read no other paged table
    /// (`compaction`, `shadow_denoise`) are compiled for.
    pub fn lights_only(self) -> TablePages {
        match self.lights > 1 {
            true => TablePages { object_shift: self.object_shift, lights: self.lights, ..TablePages::default() },
            false => TablePages::default(),
        }
    }

    /// The pages of `scene`'s tables on a device with `limits`; `None` past [`MAX_PAGES`].
    pub fn of_scene(scene: &hyrt_core::frame::PreparedScene, limits: &wgpu::Limits) -> Option<TablePages> {
        let (nodes, slots) = bvh_counts(scene);
        let (nodes, slots) = (nodes as u64, slots as u64);
        let g = &scene.geometry;
        let triangles = g.triangles.stored_records().len() as u64;
        // Past 2^32 words the tables cannot be indexed: more pages than any device has.
        let surface = g.surface.layout().map_or(u64::MAX, |l| l.bytes() / WORD_BYTES);
        let mesh = if g.triangles.has_references() { g.triangles.mesh_word_count() as u64 } else { 0 };
        let objects = g.objects.len() as u64;
        let placements = if g.triangles.has_references() { objects } else { 0 };
        let instances = scene.levels.as_ref().map_or(0, |l| l.instances.len() as u64);
        let lights = (g.lights.len() + g.emitters.len()) as u64;
        Self::of_counts(triangles, slots, nodes, page_shift(limits))?
            .with_words(surface, mesh, word_page_shift(limits))?
            .with_objects([placements, objects, instances, lights], object_page_shift(limits))
    }

    /// Whether some table is paged.
    pub fn any(self) -> bool {
        Table::ALL.iter().any(|&t| self.pages(t) > 1)
    }

    /// log2 of the elements per page of `table`: [`TablePages::word_shift`] for the word
    /// tables, [`TablePages::object_shift`] for the per-object ones, else
    /// [`TablePages::shift`].
    pub fn shift_of(self, table: Table) -> u32 {
        u32::from(match table {
            t if t.is_words() => self.word_shift,
            t if t.is_per_object() => self.object_shift,
            _ => self.shift,
        })
    }

    /// Pages of `table` (1 when unpaged).
    pub fn pages(self, table: Table) -> u32 {
        let n = match table {
            Table::Triangles | Table::Normals => self.triangles,
            Table::LeafTriangles | Table::PrimIndices => self.slots,
            Table::Nodes => self.nodes,
            Table::Surface => self.surface,
            Table::MeshWords => self.mesh_words,
            Table::Placements => self.placements,
            Table::Objects => self.objects,
            Table::Instances => self.instances,
            Table::Lights => self.lights,
        };
        u32::from(n).max(1)
    }

    /// Records of `table` per page: `1 << shift` (`1 << word_shift` words for the surface
    /// tables), or every record when it is unpaged.
    pub fn page_records(self, table: Table) -> Option<u64> {
        (self.pages(table) > 1).then(|| 1u64 << self.shift_of(table))
    }

    /// Storage buffers the further pages add to a stage that binds `tables`.
    pub fn extra_bindings(self, tables: &[Table]) -> u32 {
        tables.iter().map(|&t| self.pages(t) - 1).sum()
    }

    /// The bind group layout entries of the further pages of `tables` (read-only storage,
    /// compute), for a stage with an explicit layout.
    pub fn layout_entries(self, tables: &[Table]) -> Vec<wgpu::BindGroupLayoutEntry> {
        let page = |t: Table| (1..self.pages(t)).map(move |k| crate::shader::storage_entry(page_binding(t, k), true));
        tables.iter().flat_map(|&t| page(t)).collect()
    }
}

/// One table on the device: its pages, `page_bytes` each but the last (one page when
/// unpaged, however large).
pub struct PagedBuffer {
    table: Table,
    pages: Vec<wgpu::Buffer>,
    page_bytes: u64,
}

impl PagedBuffer {
    /// Upload `data`, the records of `table`, in the pages `pages` gives it.
    pub fn upload<T: bytemuck::Pod>(ctx: &crate::GpuContext, table: Table, data: &[T], pages: TablePages) -> Self {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let label = table.name();
        match pages.page_records(table) {
            None => PagedBuffer {
                table,
                pages: vec![crate::gpu_buffer::upload(ctx, label, data)],
                page_bytes: bytes.len().max(1) as u64,
            },
            Some(records) => {
                let page_bytes = records * table.record_bytes();
                let room = page_bytes * u64::from(pages.pages(table));
                assert!(bytes.len() as u64 <= room, "{label}: {} bytes in {pages:?}", bytes.len());
                let pages = (0..pages.pages(table) as usize)
                    .map(|k| {
                        let lo = (k as u64 * page_bytes).min(bytes.len() as u64) as usize;
                        let hi = ((k as u64 + 1) * page_bytes).min(bytes.len() as u64) as usize;
                        crate::gpu_buffer::upload::<u8>(ctx, &format!("{label} page {k}"), &bytes[lo..hi])
                    })
                    .collect();
                PagedBuffer { table, pages, page_bytes }
            }
        }
    }

    /// The first page: the table's own binding.
    pub fn first(&self) -> &wgpu::Buffer {
        &self.pages[0]
    }

    /// The further pages' bind group entries, at [`page_binding`]: none when unpaged.
    pub fn further(&self) -> impl Iterator<Item = wgpu::BindGroupEntry<'_>> + '_ {
        self.pages.iter().enumerate().skip(1).map(|(k, b)| wgpu::BindGroupEntry {
            binding: page_binding(self.table, k as u32),
            resource: b.as_entire_binding(),
        })
    }

    /// Write `bytes` at byte `offset` of the table as if it were one buffer.
    pub fn write(&self, queue: &wgpu::Queue, offset: u64, bytes: &[u8]) {
        let mut at = offset;
        let mut rest = bytes;
        while !rest.is_empty() {
            let (page, within) = (at / self.page_bytes, at % self.page_bytes);
            let n = rest.len().min((self.page_bytes - within) as usize);
            queue.write_buffer(&self.pages[page as usize], within, &rest[..n]);
            at += n as u64;
            rest = &rest[n..];
        }
    }

    /// The pages, first to last.
    pub fn pages(&self) -> &[wgpu::Buffer] {
        &self.pages
    }

    /// Bytes on the device, every page.
    pub fn size(&self) -> u64 {
        self.pages.iter().map(|b| b.size()).sum()
    }
}

/// `source` for tables split as `pages` say: for each paged table the source declares
/// (`@group(G) @binding(B) var<storage, read> NAME: array<T>;`), its further pages
/// declared at [`page_binding`] in group `G`, every `NAME[i]` rewritten to `NAME_at(i)`,
/// and that accessor appended. Unchanged where nothing is paged.
pub fn paged_source(source: &str, pages: TablePages) -> String {
    let mut out = source.to_string();
    for table in Table::ALL {
        let n = pages.pages(table);
        if n <= 1 {
            continue;
        }
        let name = table.name();
        let Some((group, element)) = declaration(&out, name) else { continue };
        out = out.replace(&format!("arrayLength(&{name})"), &paged_length(table, n, pages.shift_of(table)));
        out = rewrite_indexing(&out, name, &table.accessor());
        for k in 1..n {
            out += &format!(
                "@group({group}) @binding({}) var<storage, read> {name}_page{k}: array<{element}>;\n",
                page_binding(table, k)
            );
        }
        out += &accessor(table, &element, n, pages.shift_of(table));
    }
    out
}

/// The elements of `table` in `pages` pages of `1 << shift` records, in WGSL: every page
/// but the last full (each is uploaded at its records' size, [`PagedBuffer::upload`]),
/// and the last page's `arrayLength`.
fn paged_length(table: Table, pages: u32, shift: u32) -> String {
    let full = (u64::from(pages - 1) * u64::from(table.elements_per_record())) << shift;
    let full = u32::try_from(full).expect("a paged table of fewer than 2^32 elements");
    format!("({full}u + arrayLength(&{}_page{}))", table.name(), pages - 1)
}

/// The group and element type of `name`'s read-only storage declaration in `source`.
fn declaration(source: &str, name: &str) -> Option<(u32, String)> {
    let needle = format!(" var<storage, read> {name}: array<");
    let at = source.find(&needle)?;
    let line_start = source[..at].rfind('\n').map_or(0, |i| i + 1);
    let head = &source[line_start..at];
    let group = head.split("@group(").nth(1)?.split(')').next()?.trim().parse().ok()?;
    let rest = &source[at + needle.len()..];
    let element = rest[..rest.find(">;")?].to_string();
    Some((group, element))
}

/// `source` with every `name[expr]` (the identifier alone, not a longer one ending in it,
/// nor a field `.name`) replaced by `accessor(expr)`; brackets inside `expr` are matched.
fn rewrite_indexing(source: &str, name: &str, accessor: &str) -> String {
    let pattern = format!("{name}[");
    let mut out = String::with_capacity(source.len());
    let mut rest = source;
    while let Some(at) = rest.find(&pattern) {
        let before = rest[..at].chars().next_back();
        let continues = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '.';
        if before.is_some_and(continues) {
            out += &rest[..at + pattern.len()];
            rest = &rest[at + pattern.len()..];
            continue;
        }
        out += &rest[..at];
        out += accessor;
        out += "(";
        let mut depth = 1;
        let body = &rest[at + pattern.len()..];
        let mut end = body.len();
        for (i, c) in body.char_indices() {
            match c {
                '[' => depth += 1,
                ']' => {
                    depth -= 1;
                    if depth == 0 {
                        end = i;
                        break;
                    }
                }
                _ => {}
            }
        }
        assert!(end < body.len(), "unmatched bracket after {name}[");
        // The index may read the table too (`name[name[i]]`).
        out += &rewrite_indexing(&body[..end], name, accessor);
        out += ")";
        rest = &body[end + 1..];
    }
    out + rest
}

/// `NAME_at(i)` ([`Table::accessor`]): element `i` of the table as if unpaged, read from
/// its page.
fn accessor(table: Table, element: &str, pages: u32, shift: u32) -> String {
    let name = table.name();
    let function = table.accessor();
    let per = table.elements_per_record();
    // The page of element `i` (record `i / per`), and where it starts in elements.
    let (page, local) = match per {
        1 => (format!("i >> {shift}u"), format!("i & {}u", (1u64 << shift) - 1)),
        _ => (format!("(i / {per}u) >> {shift}u"), format!("i - page * ({per}u << {shift}u)")),
    };
    let mut s = format!(
        "// Element `i` of `{name}` as if it were one array: page `i >> {shift}` of its records\n\
         // (hyrt_gpu::paging).\nfn {function}(i: u32) -> {element} {{\n    let page = {page};\n    let local = {local};\n"
    );
    if table.is_words() {
        // Every page read and one selected, without branches: the surface tables are read
        // at many places of the largest stages, and a branch at each (a switch, or ifs)
        // crashed lavapipe (Mesa 24: SIGSEGV in its command thread) in the bounce stages.
        // A read past a shorter page's end is in bounds of the binding or reads a value
        // WGSL allows (never the one selected).
        s += &format!("    var e = {name}[local];\n");
        for k in 1..pages {
            s += &format!("    e = select(e, {name}_page{k}[local], page == {k}u);\n");
        }
        return s + "    return e;\n}\n";
    }
    s += "    switch page {\n";
    for k in 1..pages {
        s += &format!("        case {k}u: {{\n            return {name}_page{k}[local];\n        }}\n");
    }
    s += &format!("        default: {{\n            return {name}[local];\n        }}\n    }}\n}}\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pages_fit_one_binding() {
        assert_eq!(TablePages::UNPAGED, TablePages::default());
        let limits = wgpu::Limits { max_storage_buffer_binding_size: 128 << 20, ..wgpu::Limits::default() };
        assert_eq!(page_shift(&limits), 21);
        for t in Table::ALL.into_iter().filter(|t| !t.is_per_object()) {
            assert!(t.record_bytes() << 21 <= 128 << 20, "{t:?}");
        }
        // Four dragons, stored: 3,485,656 records, 2 pages; everything else one page.
        let p = TablePages::of_counts(3_485_656, 3_485_656, 1_500_000, 21).unwrap();
        assert_eq!((p.pages(Table::Normals), p.pages(Table::PrimIndices), p.pages(Table::Nodes)), (2, 2, 1));
        assert_eq!(TablePages::of_counts(2_097_152, 10, 10, 21), Some(TablePages::default()));
        assert_eq!(TablePages::of_counts(16 << 21, 10, 10, 21).map(|p| p.triangles), Some(16));
        assert_eq!(TablePages::of_counts((16 << 21) + 1, 10, 10, 21), None);
    }

    #[test]
    fn indexing_is_rewritten_through_the_pages() {
        let source = "@group(1) @binding(4) var<storage, read> triangles: array<TriangleRecord>;\n\
                      @group(1) @binding(5) var<storage, read> normals: array<f32>;\n\
                      fn f(i: u32) -> f32 { return triangles[ids[i]].v0.x + normals[9u * i] + my_triangles[i]; }\n";
        let pages = TablePages { shift: 3, triangles: 3, slots: 1, nodes: 1, ..TablePages::default() };
        let s = paged_source(source, pages);
        assert!(s.contains("return triangles_at(ids[i]).v0.x + normals_at(9u * i) + my_triangles[i];"), "{s}");
        assert!(s.contains("@group(1) @binding(65) var<storage, read> triangles_page1: array<TriangleRecord>;"));
        assert!(s.contains("@group(1) @binding(82) var<storage, read> normals_page2: array<f32>;"));
        assert!(s.contains("let local = i - page * (9u << 3u);"));
        assert_eq!(paged_source(source, TablePages::default()), source);
    }

    /// The surface tables are paged by word, in pages of a whole binding (not of 48-byte
    /// records), independently of the record tables; their accessor is `surface_word`
    /// (the stages define a `surface_at` of their own), and neither `surface_at(` nor
    /// `surfaces[i]` nor a field `.surface[` is rewritten.
    #[test]
    fn surface_words_are_paged_by_word() {
        let limits = wgpu::Limits { max_storage_buffer_binding_size: 128 << 20, ..wgpu::Limits::default() };
        assert_eq!(word_page_shift(&limits), 25);
        assert_eq!(Table::Surface.record_bytes() << 25, 128 << 20);
        // 300 MiB of surface words: 3 pages of 128 MiB; the record tables unpaged.
        let p = TablePages::default().with_words(300 << 18, 0, 25).unwrap();
        assert_eq!((p.pages(Table::Surface), p.pages(Table::Triangles)), (3, 1));
        assert_eq!((p.shift, p.word_shift, p.page_records(Table::Surface)), (0, 25, Some(1 << 25)));
        assert!(p.any());
        assert_eq!(TablePages::default().with_words(1 << 25, 0, 25), Some(TablePages::default()));
        assert_eq!(TablePages::default().with_words(16 << 25, 0, 25).map(|p| p.surface), Some(16));
        assert_eq!(TablePages::default().with_words((16 << 25) + 1, 0, 25), None);
        // Both kinds paged: each by its own shift.
        let both = TablePages::of_counts(3 << 21, 10, 10, 21).unwrap().with_words(5 << 25, 0, 25).unwrap();
        assert_eq!((both.pages(Table::Normals), both.pages(Table::Surface)), (3, 5));
        assert_eq!((both.shift_of(Table::Normals), both.shift_of(Table::Surface)), (21, 25));

        let source = "@group(0) @binding(9) var<storage, read> surface: array<u32>;\n\
                      fn f(at: u32) -> u32 { return surface[surface[at] + 1u] + surfaces[at].x + out.surface[0]; }\n\
                      fn g() -> SurfaceRecord { return surface_at(0u); }\n";
        let pages = TablePages { word_shift: 4, surface: 3, ..TablePages::default() };
        let s = paged_source(source, pages);
        assert!(s.contains("return surface_word(surface_word(at) + 1u) + surfaces[at].x + out.surface[0]; }"), "{s}");
        assert!(s.contains("return surface_at(0u);"), "{s}");
        assert!(s.contains("@group(0) @binding(145) var<storage, read> surface_page1: array<u32>;"), "{s}");
        assert!(s.contains("@group(0) @binding(146) var<storage, read> surface_page2: array<u32>;"), "{s}");
        assert!(s.contains("fn surface_word(i: u32) -> u32 {"), "{s}");
        assert!(s.contains("let page = i >> 4u;") && s.contains("let local = i & 15u;"), "{s}");
        assert!(s.contains("e = select(e, surface_page2[local], page == 2u);") && !s.contains("switch"), "{s}");
        // Paged record tables alone leave the surface tables as written.
        let records = TablePages { shift: 3, triangles: 3, slots: 1, nodes: 1, ..TablePages::default() };
        assert_eq!(paged_source(source, records), source);
    }
    /// The per-object tables are paged by their own shift (a page of 112-byte placements
    /// within one binding), independently of the others; `arrayLength` of a paged table
    /// counts its full pages and the last page's records.
    #[test]
    fn objects_are_paged_by_placement() {
        let limits = wgpu::Limits { max_storage_buffer_binding_size: 128 << 20, ..wgpu::Limits::default() };
        assert_eq!(object_page_shift(&limits), 20);
        for t in Table::ALL.into_iter().filter(|t| t.is_per_object()) {
            assert!(t.record_bytes() << 20 <= 128 << 20, "{t:?}");
        }
        // 384 KiB bindings: 2,048 placements a page (3,510 would fit), 8,192 world records.
        let small = wgpu::Limits { max_storage_buffer_binding_size: 384 << 10, ..wgpu::Limits::default() };
        assert_eq!((object_page_shift(&small), page_shift(&small)), (11, 13));
        assert!(Table::Placements.record_bytes() << 11 <= 384 << 10);
        // 2.5 million objects by reference, as many instances: three pages of each.
        let p = TablePages::default().with_objects([2_500_000, 2_500_000, 2_500_000, 0], 20).unwrap();
        assert_eq!((p.pages(Table::Placements), p.pages(Table::Objects), p.pages(Table::Instances)), (3, 3, 3));
        assert_eq!((p.shift_of(Table::Objects), p.shift_of(Table::Triangles), p.pages(Table::Triangles)), (20, 0, 1));
        assert_eq!(p.page_records(Table::Placements), Some(1 << 20));
        assert_eq!(p.extra_bindings(&Table::ALL), 6);
        // Stored objects: no placements, their records paged alone.
        let stored = TablePages::default().with_objects([0, 1_500_000, 0, 10], 20).unwrap();
        assert_eq!((stored.pages(Table::Placements), stored.pages(Table::Objects)), (1, 2));
        assert_eq!(TablePages::default().with_objects([1 << 20, 1 << 20, 0, 5], 20), Some(TablePages::default()));
        assert_eq!(TablePages::default().with_objects([0, 16 << 20, 0, 0], 20).map(|p| p.objects), Some(16));
        assert_eq!(TablePages::default().with_objects([0, 0, (16 << 20) + 1, 0], 20), None);
        // 1.5 million emissive triangles: the lights in two pages, alone of their table's
        // stages (`compaction`, `shadow_denoise`).
        let lit = stored.with_objects([0, 10, 0, 1_500_000], 20).unwrap();
        assert_eq!((lit.pages(Table::Lights), lit.pages(Table::Objects)), (2, 1));
        assert_eq!(lit.lights_only(), TablePages { object_shift: 20, lights: 2, ..TablePages::default() });
        assert_eq!(stored.lights_only(), TablePages::default());
        // Every kind paged, each by its shift.
        let all = TablePages::of_counts(3 << 21, 10, 10, 21).unwrap().with_words(5 << 25, 0, 25).unwrap();
        let all = all.with_objects([0, 3 << 20, 0, 0], 20).unwrap();
        assert_eq!((all.pages(Table::Normals), all.pages(Table::Surface), all.pages(Table::Objects)), (3, 5, 3));

        let source = "@group(0) @binding(13) var<storage, read> placements: array<PlacementRecord>;\n\
                      fn n() -> u32 { return arrayLength(&placements) + placements[2u].first_triangle; }\n";
        let pages = TablePages { object_shift: 11, placements: 3, ..TablePages::default() };
        let s = paged_source(source, pages);
        assert!(
            s.contains("return (4096u + arrayLength(&placements_page2)) + placements_at(2u).first_triangle;"),
            "{s}"
        );
        assert!(s.contains("@group(0) @binding(177) var<storage, read> placements_page1: array<PlacementRecord>;"));
        assert!(s.contains("let page = i >> 11u;") && s.contains("let local = i & 2047u;"), "{s}");
        assert_eq!(paged_source(source, TablePages { object_shift: 11, objects: 3, ..TablePages::default() }), source);
    }
}
