//! Command-line entry point: `meshatlas serve` and `meshatlas run`.

fn main() {
    println!("meshatlas {}", env!("CARGO_PKG_VERSION"));
}
