dynid_macros::arm!(notrust, root = "tests/ui/fixtures");

fn main() {}
