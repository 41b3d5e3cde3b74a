"""TRENet training code: a numpy reference of the serving geometry and its shared test vectors."""
