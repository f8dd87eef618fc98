"""Review: plots and stage inspection."""
