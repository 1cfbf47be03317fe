fn main() {
    // esp-hal's linker script (memory map, sections, vector table) for the image only.
    println!("cargo:rustc-link-arg-bins=-Tlinkall.x");
    // defmt's sections (esp-hal, esp-rtos and embassy log and panic through defmt; the
    // format strings go to a non-loaded section, fw_esp::defmt_sink).
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
