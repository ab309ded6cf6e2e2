"""Pictures of results beyond time plots: the delta robot drawn from its recorded joint angles."""
