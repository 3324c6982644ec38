fn main() {
    let (c, s) = mbsolve_codegen::mbsolve_builtin();
    print!("{c}");
    eprintln!("{s:?}");
}
