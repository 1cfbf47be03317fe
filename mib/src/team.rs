//! Team coordination without the ground: inter-robot link, leader selection timing and
//! capacities, limited leader authority. One place for every number the on-board team
//! logic, the simulator and the ground share.
