"""The paper's experiment (section 3): tasks, fitness, evolution of the controllers, the tests."""
