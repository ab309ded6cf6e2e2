"""The modules the equation compiler generates (an FMU carries its model's here)."""

__all__: list[str] = []
