"""What people look at: Rerun recordings and matplotlib figures."""
