//! The GPU context: an adapter is found (lavapipe in CI) and buffers round-trip.
//!
//! GPU tests need a Vulkan adapter. In CI (`CI` set) a missing adapter is a
//! failure; locally the test says so and skips.

mod common;

use common::test_context;
use hyrt_gpu::{gpu_buffer, AdapterPolicy, GpuContext};

#[test]
fn context_finds_an_adapter_and_round_trips_a_buffer() {
    let Some(ctx) = test_context() else { return };
    eprintln!("adapter: {}", ctx.describe());
    let data: Vec<u32> = (0..1000).map(|i| i * 3 + 1).collect();
    let buf = gpu_buffer::upload(&ctx, "test", &data);
    assert_eq!(gpu_buffer::read_back::<u32>(&ctx, &buf, data.len()).unwrap(), data);
    let empty = gpu_buffer::upload::<u32>(&ctx, "empty", &[]);
    assert_eq!(empty.size(), 4, "empty tables get one element");
}

#[test]
fn context_hardware_only_policy_rejects_software_adapters() {
    match GpuContext::new(AdapterPolicy::HardwareOnly) {
        Ok(ctx) => assert!(!hyrt_gpu::context::is_software(&ctx.info), "{}", ctx.describe()),
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("HYRT_GPU_ALLOW_SOFTWARE") || msg.contains("no GPU adapter"), "{msg}");
        }
    }
}

#[test]
fn context_on_a_callers_instance_takes_the_adapter_new_takes() {
    let Some(ctx) = test_context() else { return };
    let instance = GpuContext::vulkan_instance(None);
    let mine = GpuContext::with_instance(&instance, None, AdapterPolicy::AllowSoftware).unwrap();
    assert_eq!(mine.info.name, ctx.info.name);
    assert_eq!(mine.adapter.get_info().name, ctx.adapter.get_info().name);
    assert_eq!((mine.primitive_index, mine.timestamps), (ctx.primitive_index, ctx.timestamps));
}
