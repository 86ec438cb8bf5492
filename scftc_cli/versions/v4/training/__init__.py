"""``scftc-v4``'s trainers and tuning boxes."""
