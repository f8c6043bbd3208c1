"""The world the crane moves in: scenes, collision bodies and checks."""
