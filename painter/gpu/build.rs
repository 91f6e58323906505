//! Validates every WGSL variant the crate compiles with naga, so that a
//! shader error fails `cargo build` with naga's message instead of failing
//! the first frame.

include!("src/shader_source.rs");

fn validate(name: &str, source: &str) {
    let module = match naga::front::wgsl::parse_str(source) {
        Ok(m) => m,
        Err(e) => panic!("{name}: WGSL does not parse:\n{}", e.emit_to_string(source)),
    };
    let mut validator = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all());
    if let Err(e) = validator.validate(&module) {
        panic!("{name}: WGSL does not validate:\n{}", e.emit_to_string(source));
    }
}

fn main() {
    println!("cargo:rerun-if-changed=../../shaders");
    println!("cargo:rerun-if-changed=src/shader_source.rs");
    validate("g3.wgsl", &g3_source());
    validate("raycast.wgsl (f32)", &raycast_source(Precision::F32));
    validate("raycast.wgsl (f16)", &raycast_source(Precision::F16));
    validate("digest.wgsl", DIGEST_WGSL);
}
