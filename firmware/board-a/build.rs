fn main() {
    // esp-hal's linker script (memory map, sections, vector table) for the image only.
    println!("cargo:rustc-link-arg-bins=-Tlinkall.x");
}
