"""One Drake LeafSystem a module: the F/T sensor, contact truth, controller, compensator,
detector and Meshcat wrench arrows. Each documents its ports (sizes, units, frames)."""
