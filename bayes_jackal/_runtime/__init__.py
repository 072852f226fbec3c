"""The runtime under the data path: errors, defaults, files and locks, interrupts,
progress, executors and threads. Private: the public errors are ``bayes_jackal``'s."""
