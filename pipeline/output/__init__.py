"""What a run writes: results.json, ParaView fields, the report, the picture and plots."""
