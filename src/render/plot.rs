//! Charts drawn with plotters into an in-memory RGB buffer, with the DejaVu Sans font embedded in
//! the binary (no fontconfig, no files): B along each surface, the kernel matrix magnitudes and
//! the sorted coefficient magnitudes.

use crate::math::field::Field;
use crate::methods::compress::MagnitudePicture;
use crate::result::Coefficients;
use crate::scene::{Job, SceneKind};
use image::RgbImage;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::error::Error;
use std::sync::Once;

/// DejaVu Sans (licence in `assets/fonts/LICENSE-DejaVu.txt`).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
const SANS: &str = "sans-serif";

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
type Drawn<T> = Result<T, Box<dyn Error>>;

const CHANNELS: [(&str, RGBColor); 3] = [
    ("R", RGBColor(214, 39, 40)),
    ("G", RGBColor(44, 160, 44)),
    ("B", RGBColor(31, 119, 180)),
];

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font(SANS, FontStyle::Normal, FONT)
            .map_err(|_| ())
            .expect("the embedded font parses");
    });
}

/// Draws on a white `w × h` canvas and returns the pixels and what `draw` returned.
fn canvas<T>(w: u32, h: u32, draw: impl FnOnce(&Area<'_>) -> Drawn<T>) -> (RgbImage, T) {
    let mut buf = vec![255u8; w as usize * h as usize * 3];
    let value = draw_on(&mut buf, w, h, draw);
    (
        RgbImage::from_raw(w, h, buf).expect("buffer of w × h × 3"),
        value,
    )
}

fn draw_on<T>(buf: &mut [u8], w: u32, h: u32, draw: impl FnOnce(&Area<'_>) -> Drawn<T>) -> T {
    register_font();
    let root = BitMapBackend::with_buffer(buf, (w, h)).into_drawing_area();
    let value = draw(&root).unwrap_or_else(|e| panic!("drawing a {w}×{h} chart failed: {e}"));
    root.present().expect("presenting into memory cannot fail");
    value
}

/// One line of a chart: label, colour, points.
struct Series {
    label: String,
    color: RGBColor,
    points: Vec<(f64, f64)>,
}

/// B along a field, sampled inside every leaf so that jumps between cells stay visible;
/// `x` maps s ∈ [0,1] to the plotted abscissa.
fn samples(f: &Field, channel: Option<usize>, x: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
    let per_leaf = (256 / f.leaves.len().max(1)).clamp(2, 32);
    let mut leaves: Vec<_> = f.leaves.iter().collect();
    leaves.sort_by(|a, b| a.s[0].total_cmp(&b.s[0]));
    let mut out = Vec::new();
    for leaf in leaves {
        for i in 0..=per_leaf {
            let s = leaf.s[0] + (leaf.s[1] - leaf.s[0]) * i as f64 / per_leaf as f64;
            let v = f.eval_leaf(leaf, s, 0.0);
            let y = match channel {
                Some(c) => v[c],
                None => (v[0] + v[1] + v[2]) / 3.0,
            };
            out.push((x(s), y));
        }
    }
    out
}

fn channels_differ(fields: &[Field]) -> bool {
    fields.iter().any(|f| {
        f.leaves.iter().flat_map(|l| &l.coeffs).any(|c| {
            (c[0] - c[1]).abs() > 1e-12 * c[0].abs().max(1.0)
                || (c[0] - c[2]).abs() > 1e-12 * c[0].abs().max(1.0)
        })
    })
}

/// `image.png` of flatland and fredholm: B against the parameter along each surface, one panel
/// per surface (up to six; more share one chart), one line per channel when channels differ.
pub(super) fn radiosity(job: &Job, names: &[String], fields: &[Field], w: u32, h: u32) -> RgbImage {
    let (domain, xdesc, ydesc) = match &job.scene.kind {
        SceneKind::Fredholm(f) => (f.domain, "x", "B(x)"),
        _ => (
            [0.0, 1.0],
            "s (position along the surface, 0 to 1)",
            "B (W/m)",
        ),
    };
    let x = |s: f64| domain[0] + s * (domain[1] - domain[0]);
    let differ = channels_differ(fields);
    let title = job
        .scene
        .name
        .clone()
        .unwrap_or_else(|| "Radiosity".to_string());
    // one panel per surface: a column of up to six, then a grid; when the panels would be too
    // small to read, every surface in one chart, one after another along the x axis
    let n = fields.len();
    let cols = n.div_ceil(6);
    let rows = n.div_ceil(cols);
    if (w as usize) / cols < 200 || (h as usize) / rows < 120 {
        return along(&title, fields, differ, ydesc, w, h);
    }
    canvas(w, h, |root| {
        root.fill(&WHITE)?;
        // long names get a smaller title rather than being cut at the edges
        let small = (h as usize) / rows < 220;
        let title = with_channels(&title, small && differ);
        let size = title_size(w, &title, 0.55, 11.0..=18.0);
        let root = root.titled(&title, (SANS, size))?;
        let panels = root.split_evenly((rows, cols));
        for ((area, f), name) in panels.iter().zip(fields).zip(names) {
            let series = if differ {
                CHANNELS
                    .iter()
                    .enumerate()
                    .map(|(c, (label, color))| Series {
                        label: format!("{name} {label}"),
                        color: *color,
                        points: samples(f, Some(c), x),
                    })
                    .collect()
            } else {
                vec![Series {
                    label: name.clone(),
                    color: CHANNELS[2].1,
                    points: samples(f, Some(0), x),
                }]
            };
            line_chart(area, name, domain, xdesc, ydesc, series)?;
        }
        Ok(())
    })
    .0
}

/// B along every surface in one chart, surface i over [i, i + 1] of the x axis, for scenes with
/// more surfaces than panels fit in the image.
fn along(title: &str, fields: &[Field], differ: bool, ydesc: &str, w: u32, h: u32) -> RgbImage {
    let n = fields.len();
    let channels: Vec<usize> = if differ { vec![0, 1, 2] } else { vec![0] };
    // one run of points per surface and channel, so that no line joins two surfaces
    let runs: Vec<(usize, Vec<(f64, f64)>)> = fields
        .iter()
        .enumerate()
        .flat_map(|(i, f)| {
            channels
                .iter()
                .map(move |&c| (c, samples(f, Some(c), |s| i as f64 + s)))
        })
        .collect();
    let (lo, hi) = runs
        .iter()
        .flat_map(|(_, p)| p)
        .fold((0.0f64, f64::MIN_POSITIVE), |(lo, hi), &(_, y)| {
            (lo.min(y), hi.max(y))
        });
    let pad = (hi - lo) * 0.05;
    let title = with_channels(title, differ);
    canvas(w, h, |root| {
        root.fill(&WHITE)?;
        let size = title_size(w, &title, 0.55, 11.0..=18.0);
        let mut chart = ChartBuilder::on(root)
            .caption(&title, (SANS, size))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(62)
            .build_cartesian_2d(0f64..n as f64, (lo - pad.min(lo.abs()))..(hi + pad))?;
        chart
            .configure_mesh()
            .label_style((SANS, 11))
            .x_labels(n.min(16) + 1)
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.3}"))
            .x_desc(format!(
                "surface i over [i, i + 1], s from 0 to 1 within it ({n} surfaces in document order)"
            ))
            .y_desc(ydesc)
            .light_line_style(WHITE.mix(0.0))
            .draw()?;
        chart.draw_series((1..n).map(|i| {
            PathElement::new(
                vec![(i as f64, lo - pad), (i as f64, hi + pad)],
                BLACK.mix(0.15),
            )
        }))?;
        for (c, points) in runs {
            let color = if differ {
                CHANNELS[c].1
            } else {
                CHANNELS[2].1
            };
            chart.draw_series(LineSeries::new(points, color.stroke_width(1)))?;
        }
        Ok(())
    })
    .0
}

/// `surfaces/<name>.png`: B over one surface in its own colours, with axes and a colour bar:
/// the (s, t) square with t upwards (3D), or a strip along s (flatland, fredholm). Each
/// channel of B maps linearly (then sRGB-like) from `range.0` (black) to `range.1` (white),
/// which the bar shows in B.
pub fn surface(title: &str, f: &Field, range: (f64, f64)) -> RgbImage {
    let square = f.dims == 2;
    let (lo, hi) = range;
    let tone = |v: [f64; 3]| super::tone(v.map(|x| x - lo), hi - lo);
    // the colour bar in the surface's own colour: the colour of a point whose B is the bar's
    // value times the hue of the surface's mean (grey for a grey surface)
    let mean = f.mean();
    let top = mean.iter().cloned().fold(0.0f64, f64::max);
    let hue = if top > 0.0 && top.is_finite() {
        mean.map(|m| (m / top).max(0.0))
    } else {
        [1.0; 3]
    };
    let (w, h) = if square { (440u32, 360u32) } else { (660, 150) };
    let (mut img, (xr, yr)) = canvas(w, h, |root| {
        root.fill(&WHITE)?;
        let size = title_size(w, title, 0.6, 10.0..=15.0);
        let root = root.titled(title, (SANS, size))?;
        let (left, right) = root.split_horizontally(w - 100);
        let mut chart = ChartBuilder::on(&left)
            .margin(8)
            .x_label_area_size(32)
            .y_label_area_size(if square { 36 } else { 8 })
            .build_cartesian_2d(0f64..1f64, 0f64..1f64)?;
        let mut mesh = chart.configure_mesh();
        mesh.disable_mesh()
            .label_style((SANS, 11))
            .x_labels(5)
            .y_labels(5)
            .x_desc("s")
            .x_label_formatter(&|v| format!("{v:.2}"))
            .y_label_formatter(&|v| format!("{v:.2}"));
        if square {
            mesh.y_desc("t");
        } else {
            mesh.disable_y_axis();
        }
        mesh.draw()?;
        let range = chart.plotting_area().get_pixel_range();
        let mut bar = ChartBuilder::on(&right)
            .margin_top(8)
            .margin_bottom(if square { 40 } else { 8 })
            .margin_right(30)
            .y_label_area_size(52)
            .build_cartesian_2d(0f64..1f64, lo..hi)?;
        bar.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .label_style((SANS, 10))
            .y_labels(if square { 6 } else { 4 })
            .y_desc("B")
            .y_label_formatter(&|v| short(*v))
            .draw()?;
        let steps = 64;
        bar.draw_series((0..steps).map(|i| {
            let a = lo + (hi - lo) * i as f64 / steps as f64;
            let b = lo + (hi - lo) * (i + 1) as f64 / steps as f64;
            let g = tone(hue.map(|c| c * (a + b) / 2.0)).0;
            Rectangle::new([(0.0, a), (1.0, b)], RGBColor(g[0], g[1], g[2]).filled())
        }))?;
        bar.plotting_area().draw(&Rectangle::new(
            [(0.0, lo), (1.0, hi)],
            BLACK.stroke_width(1),
        ))?;
        Ok(range)
    });
    let (x0, y0, pw, ph) = area_pixels(&xr, &yr);
    for py in 0..ph.min(h.saturating_sub(y0)) {
        let t = 1.0 - (py as f64 + 0.5) / ph as f64;
        for px in 0..pw.min(w.saturating_sub(x0)) {
            let s = (px as f64 + 0.5) / pw as f64;
            // a triangle is the half s + t ≤ 1 of its square of parameters
            if f.tri && s + t > 1.0 {
                continue;
            }
            let b = f.eval(s, if square { t } else { 0.0 });
            img.put_pixel(x0 + px, y0 + py, tone(b));
        }
    }
    frame(&mut img, x0, y0, pw, ph);
    img
}

/// The colour of the frame around a surface's map: a dark slate that no grey of the map or
/// of the text has.
const FRAME: RGBColor = RGBColor(60, 64, 72);

/// A one-pixel frame just outside the `pw × ph` area at (x0, y0): a surface as bright as the
/// page (a light at the top of its scale) still shows where it is.
fn frame(img: &mut RgbImage, x0: u32, y0: u32, pw: u32, ph: u32) {
    let (w, h) = img.dimensions();
    if w == 0 || h == 0 {
        return;
    }
    let c = image::Rgb([FRAME.0, FRAME.1, FRAME.2]);
    let (left, top) = (x0.saturating_sub(1), y0.saturating_sub(1));
    let (right, bottom) = ((x0 + pw).min(w - 1), (y0 + ph).min(h - 1));
    for x in left..=right {
        img.put_pixel(x, top, c);
        img.put_pixel(x, bottom, c);
    }
    for y in top..=bottom {
        img.put_pixel(left, y, c);
        img.put_pixel(right, y, c);
    }
}

/// Writes `text` in the lower left corner of a rendered image, white on a dark band (the
/// scene's name on its camera view).
pub(super) fn caption(img: &mut RgbImage, text: &str) {
    let (w, h) = img.dimensions();
    let size = (h as f64 / 28.0).clamp(10.0, 16.0);
    let band = (size * 1.6) as i32;
    let mut buf = std::mem::take(img).into_raw();
    draw_on(&mut buf, w, h, |root| {
        root.draw(&Rectangle::new(
            [(0, h as i32 - band), (w as i32, h as i32)],
            BLACK.mix(0.45).filled(),
        ))?;
        root.draw(&Text::new(
            text.to_string(),
            ((size * 0.5) as i32, h as i32 - band + (size * 0.25) as i32),
            (SANS, size).into_font().color(&WHITE),
        ))?;
        Ok(())
    });
    *img = RgbImage::from_raw(w, h, buf).expect("the same buffer");
}

/// The top left corner and the size in pixels of a chart's plotting area, from its pixel
/// ranges, for the pictures that fill it pixel by pixel.
fn area_pixels(xr: &std::ops::Range<i32>, yr: &std::ops::Range<i32>) -> (u32, u32, u32, u32) {
    (
        xr.start.max(0) as u32,
        yr.start.max(0) as u32,
        (xr.end - xr.start).max(1) as u32,
        (yr.end - yr.start).max(1) as u32,
    )
}

/// A chart's title, naming the channels' colours when the chart has no legend for them.
fn with_channels(title: &str, name_them: bool) -> String {
    if name_them {
        format!("{title} (R, G, B: red, green, blue)")
    } else {
        title.to_string()
    }
}

/// The font size of a title on a `w`-pixel-wide image: smaller for a long one, rather than
/// cut at the edges (`per_char` is a character's width in sizes).
fn title_size(w: u32, title: &str, per_char: f64, range: std::ops::RangeInclusive<f64>) -> f64 {
    (w as f64 / (per_char * title.chars().count().max(1) as f64))
        .clamp(*range.start(), *range.end())
}

/// A tick label of three significant digits, without trailing zeros.
fn short(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    if (1e-3..1e5).contains(&v.abs()) {
        let s = format!("{v:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.2e}")
    }
}

fn line_chart(
    area: &Area<'_>,
    caption: &str,
    domain: [f64; 2],
    xdesc: &str,
    ydesc: &str,
    series: Vec<Series>,
) -> Drawn<()> {
    let (lo, hi) = series
        .iter()
        .flat_map(|s| &s.points)
        .fold((0.0f64, f64::MIN_POSITIVE), |(lo, hi), &(_, y)| {
            (lo.min(y), hi.max(y))
        });
    let pad = (hi - lo) * 0.05;
    let small = area.dim_in_pixel().1 < 200;
    let y_range = (lo - if lo < 0.0 { pad } else { 0.0 })..(hi + pad);
    let legend = emptiest_corner(&series, domain, [y_range.start, y_range.end]);
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (SANS, if small { 12 } else { 15 }))
        .margin(8)
        .x_label_area_size(if small { 32 } else { 40 })
        .y_label_area_size(62)
        .build_cartesian_2d(domain[0]..domain[1], y_range)?;
    let y_format = |v: &f64| format!("{v:.3}");
    let mut mesh = chart.configure_mesh();
    mesh.label_style((SANS, 11))
        .y_desc(ydesc)
        .y_label_formatter(&y_format);
    // a small panel gets a short axis name and fewer ticks, so that its labels do not run
    // into each other
    if small {
        mesh.x_desc(xdesc.split(' ').next().unwrap_or(xdesc))
            .x_labels(5)
            .y_labels(4);
    } else {
        mesh.x_desc(xdesc);
    }
    mesh.draw()?;
    for s in series {
        let color = s.color;
        chart
            .draw_series(LineSeries::new(s.points, color.stroke_width(2)))?
            .label(s.label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2))
            });
    }
    // small panels have no room for a legend: the title names the colours instead
    if !small {
        chart
            .configure_series_labels()
            .position(legend)
            .label_font((SANS, 11))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

/// The corner of the plot (a third of its width, a quarter of its height) that the fewest
/// points of `series` fall in, for the legend.
fn emptiest_corner(series: &[Series], x: [f64; 2], y: [f64; 2]) -> SeriesLabelPosition {
    let (w, h) = (x[1] - x[0], y[1] - y[0]);
    let corners = [
        (SeriesLabelPosition::UpperRight, true, true),
        (SeriesLabelPosition::UpperLeft, false, true),
        (SeriesLabelPosition::LowerRight, true, false),
        (SeriesLabelPosition::LowerLeft, false, false),
    ];
    let inside = |&(px, py): &(f64, f64), right: bool, upper: bool| {
        let in_x = if right {
            px > x[1] - w / 3.0
        } else {
            px < x[0] + w / 3.0
        };
        let in_y = if upper {
            py > y[1] - h / 4.0
        } else {
            py < y[0] + h / 4.0
        };
        in_x && in_y
    };
    corners
        .into_iter()
        .min_by_key(|&(_, right, upper)| {
            series
                .iter()
                .flat_map(|s| &s.points)
                .filter(|p| inside(p, right, upper))
                .count()
        })
        .map(|(c, _, _)| c)
        .expect("four corners")
}

/// A perceptually ordered colour map (viridis, interpolated between eight anchors), t ∈ [0,1].
pub(super) fn viridis(t: f64) -> RGBColor {
    const A: [(u8, u8, u8); 8] = [
        (68, 1, 84),
        (70, 50, 127),
        (54, 92, 141),
        (39, 127, 142),
        (31, 161, 135),
        (74, 194, 109),
        (159, 218, 58),
        (253, 231, 37),
    ];
    let t = t.clamp(0.0, 1.0) * (A.len() - 1) as f64;
    let i = (t.floor() as usize).min(A.len() - 2);
    let f = t - i as f64;
    let mix = |a: u8, b: u8| (a as f64 + (b as f64 - a as f64) * f).round() as u8;
    RGBColor(
        mix(A[i].0, A[i + 1].0),
        mix(A[i].1, A[i + 1].1),
        mix(A[i].2, A[i + 1].2),
    )
}

/// The log range shown by the sparsity picture: eight decades below the largest entry.
fn log_range(values: &[f64]) -> (f64, f64) {
    let hi = values.iter().cloned().fold(0.0f64, f64::max);
    let hi = if hi > 0.0 { hi } else { 1.0 };
    (hi * 1e-8, hi)
}

/// `sparsity.png`: |K| per entry (the largest in each block when the matrix is larger than the
/// picture), on a log colour scale with a colour bar; entries dropped by thresholding are white.
pub fn sparsity(p: &MagnitudePicture, surfaces: &[String]) -> RgbImage {
    let (w, h) = (640u32, 560u32);
    let (lo, hi) = log_range(&p.values);
    let n = (p.side * p.block) as f64;
    // the rows and columns come surface by surface, as many for each: the axes name the
    // surfaces at the middle of their blocks (numbers when there are too many to read)
    let k = surfaces.len();
    let named = (2..=24).contains(&k);
    let fit = |i: usize, chars: usize| -> String {
        let name = &surfaces[i.min(k.saturating_sub(1))];
        if name.chars().count() <= chars {
            name.clone()
        } else {
            let cut: String = name.chars().take(chars.saturating_sub(1)).collect();
            format!("{cut}…")
        }
    };
    // about 6.5 pixels a character at 11 points; the y axis has 100 pixels for its names
    let x_chars = ((480.0 / k.max(1) as f64) / 6.5).floor().max(3.0) as usize;
    // one segment per surface; the y axis counts upwards, the rows downwards
    let x_name = |v: &SegmentValue<i32>| match v {
        SegmentValue::CenterOf(i) => fit(*i as usize, x_chars),
        _ => String::new(),
    };
    let y_name = |v: &SegmentValue<i32>| match v {
        SegmentValue::CenterOf(i) => fit(k - 1 - (*i as usize).min(k - 1), 14),
        _ => String::new(),
    };
    let (mut img, (xr, yr)) = canvas(w, h, |root| {
        root.fill(&WHITE)?;
        let (title, rows, columns, bar_desc) = if p.links {
            (
                "Links: mean kernel value of each link's block",
                "receiver cell i (finest cells, surface by surface)",
                "source cell j",
                "mean K of the link (log scale)",
            )
        } else {
            (
                "Kernel matrix magnitudes |K_ij|",
                "row i",
                "column j",
                "|K| (log scale)",
            )
        };
        let (rows, columns) = if named {
            if p.links {
                ("receiver: finest cells, by surface", "source: by surface")
            } else {
                ("row i: receiving surface", "column j: source surface")
            }
        } else {
            (rows, columns)
        };
        let root = root.titled(title, (SANS, 18))?;
        let (left, right) = root.split_horizontally(w - 110);
        let range = if named {
            let mut chart = ChartBuilder::on(&left)
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(100)
                .build_cartesian_2d(
                    (0..k as i32 - 1).into_segmented(),
                    (0..k as i32 - 1).into_segmented(),
                )?;
            chart
                .configure_mesh()
                .disable_mesh()
                .label_style((SANS, 11))
                .x_labels(k)
                .y_labels(k)
                .x_desc(columns)
                .y_desc(rows)
                .x_label_formatter(&x_name)
                .y_label_formatter(&y_name)
                .draw()?;
            chart.plotting_area().get_pixel_range()
        } else {
            let mut chart = ChartBuilder::on(&left)
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(50)
                .build_cartesian_2d(0f64..n, n..0f64)?;
            chart
                .configure_mesh()
                .disable_mesh()
                .label_style((SANS, 11))
                .x_desc(columns)
                .y_desc(rows)
                .x_label_formatter(&|v| format!("{v:.0}"))
                .y_label_formatter(&|v| format!("{v:.0}"))
                .draw()?;
            chart.plotting_area().get_pixel_range()
        };
        let mut bar = ChartBuilder::on(&right)
            .margin_top(10)
            .margin_bottom(46)
            .margin_right(8)
            .y_label_area_size(62)
            .build_cartesian_2d(0f64..1f64, (lo..hi).log_scale())?;
        bar.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .label_style((SANS, 11))
            .y_desc(bar_desc)
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()?;
        let steps = 128;
        bar.draw_series((0..steps).map(|i| {
            let a = lo * (hi / lo).powf(i as f64 / steps as f64);
            let b = lo * (hi / lo).powf((i + 1) as f64 / steps as f64);
            Rectangle::new(
                [(0.0, a), (1.0, b)],
                viridis((i as f64 + 0.5) / steps as f64).filled(),
            )
        }))?;
        Ok(range)
    });
    let (x0, y0, pw, ph) = area_pixels(&xr, &yr);
    let (llo, lhi) = (lo.log10(), hi.log10());
    // At most one cell per pixel: blocks of f × f cells keep their largest magnitude, so that
    // no entry is lost to the scaling.
    let f = p.side.div_ceil((pw.min(ph) as usize).max(1)).max(1);
    let side = p.side.div_ceil(f);
    let mut pooled = vec![0.0f64; side * side];
    for (r, row) in p.values.chunks(p.side).enumerate() {
        for (c, &v) in row.iter().enumerate() {
            let cell = &mut pooled[(r / f) * side + c / f];
            *cell = cell.max(v);
        }
    }
    // One colour per cell, then nearest-neighbour scaling onto the plotting area.
    let colors: Vec<[u8; 3]> = pooled
        .iter()
        .map(|&v| {
            if v <= 0.0 || v < p.cut {
                [255, 255, 255]
            } else {
                let c = viridis((v.log10() - llo) / (lhi - llo));
                [c.0, c.1, c.2]
            }
        })
        .collect();
    let cols: Vec<usize> = (0..pw)
        .map(|px| (px as usize * side / pw as usize).min(side - 1))
        .collect();
    for py in 0..ph.min(h.saturating_sub(y0)) {
        let row = (py as usize * side / ph as usize).min(side - 1);
        for (px, &col) in cols.iter().enumerate().take(w.saturating_sub(x0) as usize) {
            img.put_pixel(
                x0 + px as u32,
                y0 + py,
                image::Rgb(colors[row * side + col]),
            );
        }
    }
    img
}

/// `coefficients.png`: the sorted kernel-coefficient magnitudes against their rank, log y axis,
/// with the keep cut marked (the last kept rank and the smallest kept magnitude).
pub fn coefficients(c: &Coefficients) -> RgbImage {
    let (w, h) = (640u32, 420u32);
    let positive = c.sorted_magnitudes.iter().cloned().filter(|v| *v > 0.0);
    let hi = positive.clone().fold(0.0f64, f64::max);
    let lo = positive.fold(f64::INFINITY, f64::min);
    let (lo, hi) = if hi > 0.0 {
        (lo.max(hi * 1e-16) / 2.0, hi * 2.0)
    } else {
        (1e-16, 1.0)
    };
    // the ranks span the whole matrix for the projection method (its dropped entries are
    // drawn past the cut), and the links' coefficients for the hierarchy, which holds no more
    let spanned = c
        .sorted_ranks
        .last()
        .map_or(0, |r| r + 1)
        .max(c.kept_entries);
    let hierarchy = spanned < c.matrix_entries && c.cut == 0.0;
    let x_max = if hierarchy { spanned } else { c.matrix_entries }.max(1) as f64;
    canvas(w, h, |root| {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(root)
            .caption("Sorted kernel coefficient magnitudes", (SANS, 18))
            .margin(10)
            // the last rank's label is centred on the right edge of the plot: room for half
            // of "1000000"
            .margin_right(32)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0f64..x_max, (lo..hi).log_scale())?;
        chart
            .configure_mesh()
            .label_style((SANS, 11))
            .x_desc("rank (largest first)")
            .y_desc("|coefficient|")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()?;
        let points: Vec<(f64, f64)> = c
            .sorted_ranks
            .iter()
            .zip(&c.sorted_magnitudes)
            .map(|(&r, &m)| (r as f64, m.max(lo)))
            .collect();
        let blue = CHANNELS[2].1;
        chart
            .draw_series(LineSeries::new(points, blue.stroke_width(2)))?
            .label("magnitude")
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 16, y)], blue.stroke_width(2))
            });
        let red = CHANNELS[0].1;
        let kept = c.kept_entries as f64;
        chart
            .draw_series(LineSeries::new(
                vec![(kept, lo), (kept, hi)],
                red.stroke_width(2),
            ))?
            .label(if hierarchy {
                format!(
                    "{} link coefficients (a full matrix: {})",
                    c.kept_entries, c.matrix_entries
                )
            } else {
                format!("cut: {} of {} kept", c.kept_entries, c.matrix_entries)
            })
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], red.stroke_width(2)));
        if c.cut > 0.0 {
            chart.draw_series(DashedLineSeries::new(
                vec![(0.0, c.cut), (x_max, c.cut)],
                6,
                4,
                red.stroke_width(1),
            ))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((SANS, 12))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        Ok(())
    })
    .0
}

/// A white image with one line of text (for an artifact that has nothing to show).
pub(super) fn message(w: u32, h: u32, text: &str) -> RgbImage {
    canvas(w, h, |root| {
        root.fill(&WHITE)?;
        root.draw(&Text::new(text, (10, h as i32 / 2), (SANS, 14).into_font()))?;
        Ok(())
    })
    .0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(points: Vec<(f64, f64)>) -> Series {
        Series {
            label: String::new(),
            color: BLACK,
            points,
        }
    }

    #[test]
    fn the_legend_goes_where_the_curves_are_not() {
        let rising = line((0..=100).map(|i| (i as f64 / 100.0, i as f64)).collect());
        let falling = line(
            (0..=100)
                .map(|i| (i as f64 / 100.0, 100.0 - i as f64))
                .collect(),
        );
        let at = |s: &Series| emptiest_corner(std::slice::from_ref(s), [0.0, 1.0], [0.0, 100.0]);
        assert!(matches!(at(&rising), SeriesLabelPosition::UpperLeft));
        assert!(matches!(at(&falling), SeriesLabelPosition::UpperRight));
        // high everywhere but at the left: the lower right is free of both
        let both = [
            line((0..=100).map(|i| (i as f64 / 100.0, 90.0)).collect()),
            line(
                (0..=100)
                    .map(|i| (i as f64 / 100.0, if i < 30 { 5.0 } else { 95.0 }))
                    .collect(),
            ),
        ];
        assert!(matches!(
            emptiest_corner(&both, [0.0, 1.0], [0.0, 100.0]),
            SeriesLabelPosition::LowerRight
        ));
    }
}
