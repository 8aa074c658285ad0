//! A simulated microcontroller running an infer-core policy blob in a fixed-rate control loop.
