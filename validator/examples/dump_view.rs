//! Writes real | render | |difference| PNG strips of every view of an entry, for eyeballing a
//! validation. `cargo run -p regolith-validator --example dump_view -- DB ENTRY OUTDIR`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let db = regolith_reader::Database::open(&a[0]).expect("db");
    let view = db.release("latest").expect("release");
    let geometry = regolith_validator::validate::entry_geometry(&view, &a[1]).expect("geometry");
    let scene = regolith_validator::render::Scene::new(&geometry);
    let light: regolith_validator::render::Light =
        serde_json::from_value(view.entry("captures").unwrap().meta["lighting"].clone()).unwrap();
    let model = regolith_validator::sensor::stored_model(&view, &a[1]).unwrap();
    let caps = view.captures("captures").unwrap();
    let images = caps.images().unwrap();
    std::fs::create_dir_all(&a[2]).unwrap();
    for (cap, cam) in [("loc01", "navcam_left"), ("loc02", "navcam_left")] {
        let (real, _, sim, r) = regolith_validator::validate::view_images(
            &view, &a[1], &scene, &light, &images, cap, cam, &model,
        )
        .unwrap();
        let (w, h) = (real.width, real.height);
        let mut strip = vec![0u8; 3 * w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                strip[y * 3 * w + x] = (real.data[i] * 255.0) as u8;
                strip[y * 3 * w + w + x] = if r.mask[i] == 255 {
                    (sim.data[i] * 255.0) as u8
                } else {
                    0
                };
                strip[y * 3 * w + 2 * w + x] = ((real.data[i] - sim.data[i]).abs() * 255.0) as u8;
            }
        }
        image::save_buffer(
            format!("{}/{cap}_{cam}.png", a[2]),
            &strip,
            (3 * w) as u32,
            h as u32,
            image::ColorType::L8,
        )
        .unwrap();
    }
}
