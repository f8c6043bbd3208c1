"""What a task produces for the vehicles: mission items, file formats, logs."""
