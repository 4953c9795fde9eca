"""The gymnasium environment and its vectorised form."""
