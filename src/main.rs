fn main() {
    println!("penumbra");
}
