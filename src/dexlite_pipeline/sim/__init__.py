"""Physics simulation: MuJoCo lift and six-direction tests."""
