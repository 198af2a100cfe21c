"""One module per notebook: the functions it calls, its figure builders and headline numbers."""
