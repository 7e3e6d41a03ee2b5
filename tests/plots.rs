//! The charts read as they should: a uniform surface is visible in its plot, a surface's colour
//! bar shows the surface's colours, the last rank of coefficients.png is not cut off at the
//! image's edge, and the sparsity plot's axes name the surfaces.

use image::RgbImage;
use serde_json::json;
use wavrad::math::field::Field;
use wavrad::render::plot;
use wavrad::result::Coefficients;
use wavrad::scene::{parse_value, Limits};

const FRAME: [u8; 3] = [60, 64, 72];

fn decode(png: &[u8]) -> RgbImage {
    image::load_from_memory(png).unwrap().to_rgb8()
}

/// The box that the frame pixels span in the map's part of the image (left of the bar).
fn framed(img: &RgbImage) -> (u32, u32, u32, u32) {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (x, y, p) in img.enumerate_pixels() {
        if p.0 == FRAME && x < img.width() - 100 {
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
    }
    assert!(
        x1 > x0 + 100 && y1 > y0 + 100,
        "no frame: {x0} {y0} {x1} {y1}"
    );
    // the frame is a closed line: every pixel of its top and left edges
    for x in x0..=x1 {
        assert_eq!(img.get_pixel(x, y0).0, FRAME, "top edge at x = {x}");
    }
    for y in y0..=y1 {
        assert_eq!(img.get_pixel(x0, y).0, FRAME, "left edge at y = {y}");
    }
    (x0, y0, x1, y1)
}

#[test]
fn a_uniform_light_is_framed_and_in_the_middle_of_its_scale() {
    // a light that reflects nothing has B = E everywhere
    let doc = json!({
        "scene": {"kind": "3d", "surfaces": [
            {"name": "light", "corners": [[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]],
             "reflectance": 0, "emission": 1},
            {"name": "floor", "corners": [[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0]],
             "reflectance": 0.5}]},
        "solver": {"order": 0, "resolution": 2},
        "output": {"image": {"width": 64, "height": 64}}
    });
    let job = parse_value(&doc, &Limits::default()).unwrap();
    let outcome = wavrad::job::run(&job, &wavrad::progress::Silent).unwrap();
    let images = wavrad::render::render_all(&job, &outcome);
    let png = images
        .files()
        .into_iter()
        .find(|(name, _)| name == "surfaces/light.png")
        .unwrap()
        .1
        .to_vec();
    let img = decode(&png);
    let (x0, y0, x1, y1) = framed(&img);
    // B = E at the middle of a scale from 0 to 2E: 0.5^(1/2.2) of white, not white
    let centre = img.get_pixel((x0 + x1) / 2, (y0 + y1) / 2).0;
    assert_eq!(centre, [186, 186, 186]);
}

#[test]
fn the_colour_bar_shows_the_surface_colours() {
    // a red wall: its map is red, and so is its bar, from black to the wall's red
    let f = Field::uniform_square(0, 2, &[[0.8, 0.2, 0.1]; 4]);
    let img = plot::surface("red wall", &f, (0.0, 1.0));
    let bar: Vec<[u8; 3]> = img
        .enumerate_pixels()
        .filter(|(x, _, _)| *x >= img.width() - 100)
        .map(|(_, _, p)| p.0)
        .collect();
    let red = bar
        .iter()
        .filter(|p| p[0] > 150 && p[0] as i32 > p[1] as i32 + 60 && p[1] > p[2])
        .count();
    assert!(red > 100, "{red} red pixels in the colour bar");
    // a grey surface keeps a grey bar
    let g = Field::uniform_square(0, 2, &[[0.5; 3]; 4]);
    let img = plot::surface("grey wall", &g, (0.0, 1.0));
    let coloured = img
        .enumerate_pixels()
        .filter(|(x, _, p)| *x >= img.width() - 100 && (p.0[0] != p.0[1] || p.0[1] != p.0[2]))
        .count();
    assert_eq!(coloured, 0);
    // and the map itself is framed
    framed(&img);
}

#[test]
fn the_last_rank_of_the_coefficient_plot_is_not_cut_off() {
    let n = 120_000usize;
    let ranks: Vec<usize> = (0..=16).map(|i| (i * (n - 1)) / 16).collect();
    let c = Coefficients {
        basis_size: 346,
        matrix_entries: n,
        kept_entries: n / 2,
        sparsity_ratio: 0.5,
        cut: 1e-6,
        sorted_magnitudes: ranks
            .iter()
            .map(|r| 10f64.powf(-(*r as f64) / 1e4))
            .collect(),
        sorted_ranks: ranks,
    };
    let img = plot::coefficients(&c);
    // nothing drawn in the last columns: the label of the last tick fits in the image
    for x in img.width() - 3..img.width() {
        for y in 0..img.height() {
            assert_eq!(img.get_pixel(x, y).0, [255, 255, 255], "at ({x}, {y})");
        }
    }
}

#[test]
fn the_sparsity_axes_name_the_surfaces() {
    let p = wavrad::methods::compress::MagnitudePicture {
        side: 8,
        values: (0..64).map(|i| 10f64.powi(-(i % 7))).collect(),
        block: 1,
        cut: 0.0,
        links: false,
    };
    let names = |n: &[&str]| -> Vec<String> { n.iter().map(|s| s.to_string()).collect() };
    let a = plot::sparsity(&p, &names(&["floor", "ceiling"]));
    let b = plot::sparsity(&p, &names(&["left wall", "light"]));
    let numbers = plot::sparsity(&p, &[]);
    // the labels are the names: other names, other pixels, in the label areas only
    assert_ne!(a, b);
    assert_ne!(a, numbers);
    let differ: Vec<(u32, u32)> = a
        .enumerate_pixels()
        .filter(|(x, y, px)| b.get_pixel(*x, *y) != *px)
        .map(|(x, y, _)| (x, y))
        .collect();
    let (x0, y0, _, y1) = framed_area(&a);
    assert!(
        differ.iter().all(|&(x, y)| x < x0 || y > y1 || y < y0),
        "the names change only the axes"
    );
}

/// The plotting area of a sparsity plot: the box of its non-white pixels left of the bar,
/// below the title.
fn framed_area(img: &RgbImage) -> (u32, u32, u32, u32) {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (x, y, p) in img.enumerate_pixels() {
        let coloured = p.0[0] != p.0[1] || p.0[1] != p.0[2];
        if coloured && x < img.width() - 110 {
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
    }
    (x0, y0, x1, y1)
}
