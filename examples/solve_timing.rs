use meshatlas::linalg::{CholeskySolver, Triplets};
use meshatlas::mesh::{EdgeId, Topology, fixtures};
use std::time::Instant;
fn main() {
    meshatlas::linalg::use_sequential_kernels();
    let m = fixtures::disk(130); // ~100k triangles, ~50k vertices
    let topo = Topology::new(&m);
    let n = m.n_vertices();
    let mut t = Triplets::new(n, n);
    for e in 0..topo.n_edges() {
        let [a, b] = topo.edges[e];
        let w = 1.0;
        t.push(a.idx(), a.idx(), w);
        t.push(b.idx(), b.idx(), w);
        t.push(a.idx().max(b.idx()), a.idx().min(b.idx()), -w);
        let _ = EdgeId::new(e);
    }
    for i in 0..n {
        t.push(i, i, 1e-3);
    }
    let s = t.to_matrix().unwrap();
    let t0 = Instant::now();
    let chol = CholeskySolver::new(&s).unwrap();
    println!("n {} factor {:.3}s", n, t0.elapsed().as_secs_f64());
    let mut x = vec![1.0; n];
    let t0 = Instant::now();
    for _ in 0..20 {
        chol.solve_in_place(&mut x);
    }
    println!("20 single solves {:.3}s", t0.elapsed().as_secs_f64());
    let mut cols = vec![vec![1.0; n], vec![2.0; n]];
    let t0 = Instant::now();
    for _ in 0..10 {
        chol.solve_columns(&mut cols).unwrap();
    }
    println!("10 two-column solves {:.3}s", t0.elapsed().as_secs_f64());
}
