//! The texture-filtering study ([`hyrt_accuracy::textures`]) on a small frame: mip maps
//! chosen by ray cones come closer to the supersampled reference than level-0 sampling,
//! which aliases on the receding checker; and the box filter is a mean.

use hyrt_accuracy::textures::{downsample, texture_speed_vs_error};

#[test]
fn ray_cone_mip_maps_beat_level_zero_against_the_supersampled_reference() {
    let (rows, md) = texture_speed_vs_error(96, 54, 2, 1);
    let rmse = |name: &str| rows.iter().find(|r| r.configuration == name).and_then(|r| r.rmse).expect(name);
    let (nearest, bilinear, trilinear) =
        (rmse("nearest, level 0"), rmse("bilinear, level 0"), rmse("trilinear (ray cones)"));
    assert!(trilinear < 0.75 * nearest && trilinear < 0.75 * bilinear, "{md}");
    assert!(rows.iter().all(|r| r.frame_ms > 0.0), "{md}");
    assert_eq!(rows.len(), 6, "{md}");
}

#[test]
fn downsampling_averages_each_block() {
    let image: Vec<[f32; 4]> = (0..16).map(|k| [k as f32, 0.0, 1.0, 1.0]).collect();
    let small = downsample(&image, 2, 2, 2);
    // 4 x 4 row-major: the top-left block holds 0, 1, 4, 5.
    assert_eq!(small[0], [2.5, 0.0, 1.0, 1.0]);
    assert_eq!(small[3], [12.5, 0.0, 1.0, 1.0]);
}
