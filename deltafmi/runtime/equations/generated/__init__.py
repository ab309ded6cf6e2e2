"""The modules the equation compiler generates (an FMU carries its model's here)."""
