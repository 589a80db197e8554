"""What a contact run writes: VTU and JSON exports, figures, and the command line's summary."""
