"""Pictures of results beyond time plots: the delta robot drawn from its recorded joint angles, with
its spherical wrist and peg, and a close-up of a peg-in-hole insertion."""

__all__: list[str] = []
