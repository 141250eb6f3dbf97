//! Link arguments only: `memory.x` comes from embassy-stm32's `memory-x`
//! feature, `link.x` from cortex-m-rt, `defmt.x` from defmt.

fn main() {
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
