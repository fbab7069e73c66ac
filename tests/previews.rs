//! The preview images show the data: patch colours on the atlas of a cube,
//! singularity dots where the sphere's crossfield singularities project,
//! faces in their patch's shaded colour, and a clear failure for a mesh
//! with nothing to draw.

use meshatlas::atlas::features::detect_features;
use meshatlas::atlas::{AtlasOptions, build_atlas};
use meshatlas::crossfield::{CrossfieldOptions, compute_crossfield};
use meshatlas::geom::Vec3;
use meshatlas::mesh::{Topology, TriMesh, fixtures};
use meshatlas::preview::canvas::{shade, shaded};
use meshatlas::preview::palette::{PATCH_PALETTE, index_color};
use meshatlas::preview::{
    Framing, Image, PreviewError, PreviewSize, atlas_patch_colors, atlas_preview, crossfield_preview, defect_edges,
    input_preview,
};
use meshatlas::progress::Progress;

const SIZE: PreviewSize = PreviewSize { width: 1200, height: 900 };

/// The pixel of `p` in view `k` of `framing` within the whole image.
fn pixel(framing: &Framing, k: usize, p: &Vec3) -> Option<(usize, usize)> {
    let (x, y) = framing.views[k].pixel_of(p, framing.view_width, framing.height)?;
    Some((x + k * framing.view_width, y))
}

/// Palette entry `c` times some brightness in `[0.3, 1]` is `px` (within rounding).
fn is_shade_of(px: [u8; 3], c: [u8; 3]) -> bool {
    let s = f64::from(px[0]) + f64::from(px[1]) + f64::from(px[2]);
    let t = f64::from(c[0]) + f64::from(c[1]) + f64::from(c[2]);
    let f = s / t;
    (0.3..=1.0).contains(&f) && (0..3).all(|i| (f64::from(px[i]) - f * f64::from(c[i])).abs() <= 2.5)
}

#[test]
fn the_atlas_of_a_cube_shows_six_patch_colours_and_faces_carry_their_patch_colour() {
    let cube = fixtures::cube(6);
    let atlas = build_atlas(&cube, &AtlasOptions::default(), &Progress::none()).expect("atlas of the cube");
    assert_eq!(atlas.patches.len(), 6);
    let colors = atlas_patch_colors(&atlas);
    let img: Image = atlas_preview(&atlas, &colors, SIZE).expect("atlas preview");
    assert_eq!((img.width, img.height), (1200, 900));

    // Six palette colours (shaded) each cover a good share of the image.
    let mut counts = [0usize; PATCH_PALETTE.len()];
    for y in 0..img.height {
        for x in 0..img.width {
            let px = img.pixel(x, y);
            for (k, c) in PATCH_PALETTE.iter().enumerate() {
                if is_shade_of(px, *c) {
                    counts[k] += 1;
                }
            }
        }
    }
    let shown = counts.iter().filter(|&&n| n > 5000).count();
    assert_eq!(shown, 6, "pixels per palette colour: {counts:?}");

    // The pixel at a front-facing triangle's centroid has its patch's colour, shaded.
    let framing = Framing::fit(&atlas.mesh.positions, SIZE).unwrap();
    let (mut checked, mut matched) = (0, 0);
    for (f, t) in atlas.mesh.triangles.iter().enumerate() {
        let [a, b, c] = t.map(|v| atlas.mesh.positions[v.idx()]);
        let n = (b - a).cross(&(c - a));
        for (k, view) in framing.views.iter().enumerate() {
            if n.dot(&view.forward) >= 0.0 {
                continue;
            }
            let Some((x, y)) = pixel(&framing, k, &((a + b + c) / 3.0)) else { continue };
            checked += 1;
            let want = shaded(colors[atlas.patch_per_face[f] as usize], shade(&n, &view.forward));
            matched += usize::from(img.pixel(x, y) == want);
        }
    }
    assert!(checked > 100, "{checked} front-facing centroids");
    // Centroids under a curve line or the outline are the only misses.
    assert!(matched * 10 >= checked * 9, "{matched} of {checked} centroids in their patch colour");
}

#[test]
fn crossfield_singularities_of_the_sphere_land_on_dots_of_their_index_colour() {
    let sphere = fixtures::icosphere(3);
    let topo = Topology::new(&sphere);
    let features = detect_features(&sphere, &topo, 40.0);
    let framing = Framing::fit(&sphere.positions, SIZE).unwrap();
    // Crosses: 8 singularities of index +1/4; asterisks: 12 of +1/6 (both the valence-3 colour).
    for (symmetry, count) in [(4, 8), (6, 12)] {
        let opts = CrossfieldOptions { symmetry, ..Default::default() };
        let field = compute_crossfield(&sphere, &topo, &features.is_feature_edge, &opts, &Progress::none())
            .expect("crossfield");
        assert_eq!(field.singularities.len(), count, "symmetry {symmetry}");
        let img = crossfield_preview(&sphere, &field, SIZE).expect("crossfield preview");
        for s in &field.singularities {
            let want = index_color(s.index, field.symmetry);
            assert_eq!(want, meshatlas::preview::palette::POSITIVE);
            let seen = (0..2).any(|k| pixel(&framing, k, &s.position).is_some_and(|(x, y)| img.pixel(x, y) == want));
            assert!(seen, "singularity at {:?} (index {}) is not on a dot of colour {want:?}", s.position, s.index);
        }
    }
}

#[test]
fn a_mesh_with_nothing_to_draw_fails_the_preview() {
    let empty = TriMesh { positions: Vec::new(), triangles: Vec::new() };
    assert!(matches!(input_preview(&empty, &[], SIZE), Err(PreviewError::Empty)));
    let line = TriMesh::from_raw(
        vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)],
        &[[0, 1, 2]],
    );
    let err = input_preview(&line, &[], SIZE).unwrap_err();
    assert!(matches!(err, PreviewError::Degenerate { .. }), "{err}");
    let point = TriMesh::from_raw(vec![Vec3::new(1.0, 1.0, 1.0); 3], &[[0, 1, 2]]);
    assert!(input_preview(&point, &[], SIZE).is_err());
}

#[test]
fn the_input_preview_marks_a_boundary_in_red_and_encodes_as_png() {
    let square = fixtures::square(4);
    let defects = defect_edges(&square);
    assert_eq!(defects.len(), 16, "the 4×4 square's boundary");
    let img = input_preview(&square, &defects, SIZE).expect("preview of a square");
    let red = (0..img.height).flat_map(|y| (0..img.width).map(move |x| (x, y))).filter(|&(x, y)| {
        let p = img.pixel(x, y);
        p[0] > 200 && p[1] < 60 && p[2] < 60
    });
    assert!(red.count() > 500, "the square's boundary loop is drawn in red");
    let mut png = Vec::new();
    img.write_png(&mut png).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let decoder = png::Decoder::new(std::io::Cursor::new(png));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (1200, 900));
    assert_eq!(&buf[..info.buffer_size()], &img.rgb[..]);
}

#[test]
fn patches_that_share_an_edge_never_share_a_colour() {
    // Small patches on a sphere: far more patches than palette colours.
    let sphere = fixtures::icosphere(4);
    let opts = AtlasOptions { max_patch_triangles: 150, ..Default::default() };
    let atlas = build_atlas(&sphere, &opts, &Progress::none()).expect("atlas");
    assert!(atlas.patches.len() > 2 * PATCH_PALETTE.len(), "{} patches", atlas.patches.len());
    let colors = atlas_patch_colors(&atlas);
    let topo = Topology::new(&atlas.mesh);
    let mut shared = 0;
    for e in 0..topo.n_edges() {
        let faces = topo.edge_faces(meshatlas::mesh::EdgeId::new(e));
        let patches: Vec<u32> = faces.iter().map(|f| atlas.patch_per_face[f.idx()]).collect();
        if let [p, q] = patches[..]
            && p != q
        {
            shared += 1;
            assert_ne!(colors[p as usize], colors[q as usize], "patches {p} and {q} share edge {e}");
        }
    }
    assert!(shared > 0);
}

#[test]
fn the_cube_quads_preview_marks_its_eight_corners_as_valence_three() {
    let cube = fixtures::cube(6);
    let atlas = build_atlas(&cube, &AtlasOptions::default(), &Progress::none()).unwrap();
    let topo = Topology::new(&cube);
    let aligned = detect_features(&cube, &topo, 40.0).is_feature_edge;
    let field = compute_crossfield(&cube, &topo, &aligned, &CrossfieldOptions::default(), &Progress::none()).unwrap();
    let quads =
        meshatlas::quads::build_quads(&cube, &atlas, &field, &Default::default(), &Progress::none()).expect("quads");
    let irregular = quads.quality.irregular_vertices();
    // A cube's quad mesh is regular but at its corners: three quads each.
    assert_eq!(irregular.len(), 8, "{irregular:?}");
    let img = meshatlas::preview::quads_preview(&cube, &quads.mesh, &quads.quality, SIZE).unwrap();
    let framing = Framing::fit(&cube.positions, SIZE).unwrap();
    let want = meshatlas::preview::palette::valence_color(3);
    for &v in &irregular {
        assert_eq!(quads.quality.valence[v as usize], 3);
        let p = quads.mesh.vertices.positions[v as usize];
        let seen = (0..2).any(|k| pixel(&framing, k, &p).is_some_and(|(x, y)| img.pixel(x, y) == want));
        assert!(seen, "corner {p:?} is not on a valence-3 dot");
    }
}
