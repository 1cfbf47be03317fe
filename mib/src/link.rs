//! The space link: TC/TM transfer frames, virtual channels, COP-1 and SDLS parameters
//! (CCSDS 232.0-B-4, 132.0-B-3, 232.1-B-2, 355.0-B-2). One place for every number the
//! on-board FARM, the ground's FOP and the exports share.
