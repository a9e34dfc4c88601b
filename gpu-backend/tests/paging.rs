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
