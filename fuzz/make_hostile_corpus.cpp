// Writes the hostile corpus (hostile_corpus.h) into DIR/corpus, and its escape targets into DIR/outside:
// the seeds the fuzz smoke run starts the loaders' fuzzers from. Usage: make_hostile_corpus DIR
#include <cstdio>

#include "hostile_corpus.h"

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: make_hostile_corpus DIR\n");
        return 2;
    }
    const std::filesystem::path dir = argv[1];
    for (const cb::hostile::File& f : cb::hostile::write_corpus(dir / "corpus", dir / "outside"))
        std::printf("%s\n", f.name.c_str());
    return 0;
}
