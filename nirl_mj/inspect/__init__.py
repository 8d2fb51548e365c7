"""What a person looks at: Rerun recordings, offscreen videos and montages, reward maps, report figures."""
