dynid_macros::arm!(Planar2, root = "tests/ui/fixtures");

fn main() {}
