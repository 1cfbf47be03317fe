//! MMIC-I simulator.
