//! Tables in pages on the device ([`hyrt_gpu::paging`]): what a [`PagedBuffer`] holds,
//! page after page, is the table's bytes, as uploaded and after writes that cross page
//! boundaries (a moved object's records, a refitted level's nodes).

mod common;

use hyrt_gpu::gpu_buffer::read_back;
use hyrt_gpu::paging::{PagedBuffer, Table, TablePages};

/// The table as the device holds it: every page read back, in order.
fn held(ctx: &hyrt_gpu::GpuContext, table: &PagedBuffer, words: usize) -> Vec<u32> {
    let mut all = Vec::new();
    for page in table.pages() {
        let n = (page.size() / 4) as usize;
        all.extend(read_back::<u32>(ctx, page, n).expect("read back"));
    }
    all.truncate(words);
    all
}

#[test]
fn paged_buffer_holds_and_writes_the_table_across_pages() {
    let Some(ctx) = common::test_context() else { return };
    // Four indices a page: 18 indices in 5 pages, the last half full.
    let pages = TablePages { shift: 2, triangles: 1, slots: 5, nodes: 1, ..TablePages::default() };
    let data: Vec<u32> = (0..18).map(|i| 1000 + i).collect();
    let table = PagedBuffer::upload(&ctx, Table::PrimIndices, &data, pages);
    assert_eq!(table.pages().len(), 5);
    assert_eq!(table.further().map(|e| e.binding).collect::<Vec<_>>(), [113, 114, 115, 116]);
    assert_eq!(held(&ctx, &table, 18), data);
    // Seven indices from index 3: across two page boundaries, into the last page.
    let mut expected = data.clone();
    for (at, patch) in [(3usize, (0..7).map(|i| 7 + i).collect::<Vec<u32>>()), (15, vec![42, 43, 44])] {
        table.write(&ctx.queue, at as u64 * 4, bytemuck::cast_slice(&patch));
        expected[at..at + patch.len()].copy_from_slice(&patch);
        assert_eq!(held(&ctx, &table, 18), expected, "after writing {} from {at}", patch.len());
    }
    // Unpaged: one buffer, no further pages, the same writes.
    let whole = PagedBuffer::upload(&ctx, Table::PrimIndices, &data, TablePages::default());
    assert_eq!((whole.pages().len(), whole.further().count()), (1, 0));
    whole.write(&ctx.queue, 12, bytemuck::cast_slice(&[7u32, 8, 9, 10, 11, 12, 13]));
    assert_eq!(held(&ctx, &whole, 18)[3..10], [7, 8, 9, 10, 11, 12, 13]);
}

/// Placements (112-byte records) in pages of the per-object tables' shift: every page but
/// the last holds `1 << object_shift` records, the last exactly the rest (the stages count
/// the table by the last page's `arrayLength`); writes land in their pages, across them
/// too (objects moved together).
#[test]
fn placements_are_paged_at_their_records_size() {
    let Some(ctx) = common::test_context() else { return };
    // Four placements a page: ten in 3 pages, the last two records long.
    let pages = TablePages { object_shift: 2, placements: 3, ..TablePages::default() };
    let records: Vec<[u32; 28]> = (0..10u32).map(|r| std::array::from_fn(|w| 100 * r + w as u32)).collect();
    let table = PagedBuffer::upload(&ctx, Table::Placements, &records, pages);
    assert_eq!(table.pages().iter().map(|p| p.size()).collect::<Vec<_>>(), [448, 448, 224]);
    assert_eq!(table.further().map(|e| e.binding).collect::<Vec<_>>(), [177, 178]);
    let words = records.len() * 28;
    let mut expected: Vec<u32> = records.iter().flatten().copied().collect();
    assert_eq!(held(&ctx, &table, words), expected);
    // Record 5 (page 1), then records 3 to 8 (pages 0 to 2).
    for (first, count) in [(5usize, 1usize), (3, 6)] {
        let patch: Vec<u32> = (0..count * 28).map(|w| 7_000_000 + (first * 28 + w) as u32).collect();
        table.write(&ctx.queue, (first * 112) as u64, bytemuck::cast_slice(&patch));
        expected[first * 28..(first + count) * 28].copy_from_slice(&patch);
        assert_eq!(held(&ctx, &table, words), expected, "after writing {count} from record {first}");
    }
}
