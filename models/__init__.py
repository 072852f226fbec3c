"""Robot profiles shipped with bayes_jackal (TOML files; see README, "Robot profiles")."""
