//! Exporters of the MIB to the formats ground systems read (std only).
