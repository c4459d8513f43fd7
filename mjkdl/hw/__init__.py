"""Hardware in the loop: real robots' network protocols, served and spoken."""
