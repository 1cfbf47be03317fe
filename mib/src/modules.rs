//! Plug-and-work: module types, variants and revisions (the module database), module
//! descriptors and the supported robot configurations.
