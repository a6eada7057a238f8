"""What commands show people: figures (matplotlib) and Markdown tables."""
