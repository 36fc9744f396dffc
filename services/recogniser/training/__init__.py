"""Training-data generation and model fitting for the recogniser (needs scikit-learn and hydrogen-drumkits)."""
